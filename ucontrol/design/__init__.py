"""Desired cycles by optimal control (casadi Opti/IPOPT on the symbolic model)."""
