"""validation: the harness' main job -- scenes (TOML) in, tables, figures and
``index.md`` out. ``python validation/run_all.py`` runs it.

Modules: :mod:`.scenes` (load and validate scene files), :mod:`.metrics`
(numbers from trajectories), :mod:`.experiments` (which runs a scene needs and
what they measure), :mod:`.report` (CSV tables and ``index.md``),
:mod:`.run_all` (the command line).
"""
