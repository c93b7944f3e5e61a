"""The numba loops a plan hands out before a multi-worker run
(``rk4h.validation.warm.loop_jobs``): one line per job.

    python benchmarks/warm_jobs.py [--quick] [SCENE ...]

Prints the number of jobs, then per job the scene, the job's solver string
and the kind of its loop (``scalar``, ``array``, ``rhs``, ``batch``), in the
order they are handed out. Run by two trees' Pythons on the same arguments,
the outputs compare the two warm-ups (``diff``).
"""
from __future__ import annotations

import sys


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    quick = "--quick" in argv
    names = [a for a in argv if a != "--quick"]
    bad = [a for a in names if a.startswith("-")]
    if bad:
        print(f"warm_jobs.py: unknown option {bad[0]!r} (only --quick)", file=sys.stderr)
        return 2
    from rk4h.validation.plan import plan_all
    from rk4h.validation.scenes import SceneError, load_scenes
    from rk4h.validation.warm import _loop_key, loop_jobs

    try:
        scenes = load_scenes(names or None, quick=quick)
    except SceneError as e:
        print(f"warm_jobs.py: {e}", file=sys.stderr)
        return 2
    pairs = loop_jobs(plan_all(scenes, quick=quick, figures=True, repeats=1 if quick else 3))
    print(f"{len(pairs)} jobs")
    for scene, solver in pairs:
        print(scene.name, solver, _loop_key(scene, solver)[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
