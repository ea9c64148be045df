"""Visualisation: meshcat views and matplotlib figures of scenes and runs.

Nothing is imported here: ``import ucontrol`` and runs without a viewer never load meshcat or
matplotlib. Import the module needed: :mod:`ucontrol.viz.scene_drawing` (meshcat drawing of a
scene), :mod:`~ucontrol.viz.meshcat_server` (a local viewer server),
:mod:`~ucontrol.viz.live_viewer` (a run drawn while it is computed),
:mod:`~ucontrol.viz.replay` (saved runs as animations and standalone HTML),
:mod:`~ucontrol.viz.run_figures` and :mod:`~ucontrol.viz.cycle_figures` (PNG figures, with
the notes of :mod:`~ucontrol.viz.figure_notes` on clipped samples),
:mod:`~ucontrol.viz.video` (videos and figure-quality stills rendered offline),
:mod:`~ucontrol.viz.browser_screenshot` (screenshots in headless Chromium).
"""
