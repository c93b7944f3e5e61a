"""validation: the harness' main job -- scenes (TOML) in, tables, figures and
``index.md`` out. ``python validation/run_all.py`` runs it.

The pipeline is data, flowing one way::

    scene --plan--> [RunSpec] --engine (this process | pool | Dask)--> [RunRecord]
          --measure--> tables + [Check] + figure jobs --draw/report--> reports/

Modules: :mod:`.scenes` (load and validate scene files, sweeps), :mod:`.plan`
(the runs a scene needs), :mod:`.execute` (one run, measured), :mod:`.records`
(records and their store), :mod:`.engine` (where runs execute),
:mod:`.metrics` (numbers from trajectories), :mod:`.measure` (tables and
checks from records), :mod:`.draw` and :mod:`.figures` (figures from records),
:mod:`.report` (CSV tables and ``index.md``), :mod:`.budget` (cost of a plan),
:mod:`.run_all` (the command line).
"""
