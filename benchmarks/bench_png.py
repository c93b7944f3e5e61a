"""What writing a figure's PNG costs: colour quantization and zlib settings.

Renders every figure kind of ``tests/test_figure_layout.py`` once (the
canvas ``rk4h.validation.figures.style.save`` would store), then stores each canvas as
a 256-colour palette PNG with median-cut or fast-octree quantization and
with PNG's ``optimize`` search or zlib level 6. Prints, per setting, the
median milliseconds per figure over rounds, the mean file size, and the
largest colour error of any pixel (0-255, against the RGB canvas). Run::

    python benchmarks/bench_png.py [--rounds 3]
"""
from __future__ import annotations

import argparse
import io
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))


def _canvases():
    """The RGB canvases of every figure kind, as ``rk4h.validation.figures.style.save`` draws them
    (caught by its ``SAVE_HOOK`` after the final draw)."""
    from PIL import Image

    import test_figure_layout as layout
    from rk4h.validation.figures import style

    out, original = [], style.SAVE_HOOK

    def capture(fig, path):
        w, h = fig.canvas.get_width_height()
        out.append(Image.frombuffer("RGBA", (w, h), bytes(fig.canvas.buffer_rgba()), "raw", "RGBA", 0, 1)
                   .convert("RGB"))

    style.SAVE_HOOK = capture
    try:
        with tempfile.TemporaryDirectory(prefix="rk4h-bench-png-") as tmp:
            for build in layout.BUILDERS.values():
                build(Path(tmp))
    finally:
        style.SAVE_HOOK = original
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    from PIL import Image

    canvases = _canvases()
    settings = {
        "median cut, optimize": (Image.Quantize.MEDIANCUT, {"optimize": True}),
        "median cut, zlib 6": (Image.Quantize.MEDIANCUT, {"compress_level": 6}),
        "fast octree, optimize": (Image.Quantize.FASTOCTREE, {"optimize": True}),
        "fast octree, zlib 6": (Image.Quantize.FASTOCTREE, {"compress_level": 6}),
    }
    times = {k: [] for k in settings}
    size, err = {}, {}
    for _ in range(args.rounds):
        for name, (method, kw) in settings.items():
            t0, pals, total = time.perf_counter(), [], 0
            for rgb in canvases:
                pal = rgb.quantize(colors=256, method=method, dither=Image.Dither.NONE)
                buf = io.BytesIO()
                pal.save(buf, format="PNG", **kw)
                total += len(buf.getvalue())
                pals.append(pal)
            times[name].append((time.perf_counter() - t0) / len(canvases))
            size[name] = total / len(canvases)
            err[name] = max(float(np.abs(np.asarray(p.convert("RGB"), float) - np.asarray(c, float)).max())
                            for p, c in zip(pals, canvases))
    print(f"{len(canvases)} figures, {args.rounds} rounds")
    print(f"{'setting':24s} {'ms/figure':>10s} {'KiB/figure':>11s} {'max colour error':>17s}")
    for name in settings:
        print(f"{name:24s} {1e3 * statistics.median(times[name]):10.1f} {size[name] / 1024:11.1f} "
              f"{err[name]:17.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
