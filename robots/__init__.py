"""Robot descriptions (URDF) and scenes (TOML) shipped with ucontrol as ``ucontrol.robots``."""
