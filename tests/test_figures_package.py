"""validation/figures/ as a package with one job per module, drawing from records.

* No module outside the package reaches a private name of it (``F._x``,
  ``figures._x``), and no module of the package reaches another's private name.
* The package still answers every public name the single module had.
* Modal numbers come from the record: a figure spec's record holds them
  (through the record store's serialization), the state figure job carries
  them, and the scene figures quote them without solving an eigenproblem.
"""
import math
import re
from pathlib import Path

import numpy as np
import pytest

import rk4h
from rk4h.references.exact import modal_solution
from rk4h.validation import execute, figures, records
from rk4h.validation.figures import style

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "validation" / "figures"
#: The public names of validation/figures.py before it became a package (other code calls them).
FORMER_PUBLIC = ["CROSSOVER_EMPTY", "CROSSOVER_NONE", "Caption", "DPI", "ERROR_LABELS", "FONT_MIN", "FONT_SMALL",
                 "FONT_TITLE", "GENERIC_CAPTIONS", "LONG_CHAIN", "MAX_PATH_PANELS", "PX_PER_PERIOD", "SAME_COST",
                 "SIZE", "SIZE_TALL", "SOLVER_STYLE", "convergence", "crossover", "dispersion", "energy_error",
                 "modal_energy", "plt_colors", "scene_figures", "scene_methods", "slug", "solver_style",
                 "work_precision"]


def _python_files():
    for top in ("validation", "references", "rk4core", "benchmarks", "tests"):
        yield from (p for p in (ROOT / top).rglob("*.py")
                    if PACKAGE not in p.parents and p != Path(__file__).resolve())


def _aliases(text, inside=False):
    """Names under which a module holds the figures package or one of its modules."""
    names = set(re.findall(r"(?:from\s+(?:validation|\.\.?)\s+)?import\s+figures\s+as\s+(\w+)", text))
    names |= set(re.findall(r"from\s+(?:validation\.figures|\.\.?figures|\.)\s+import\s+(?:\w+\s+as\s+)?(\w+)\b",
                            text)) & {"style", "scene", "measurement", "captions", "kit"}
    if inside:  # the package's own modules: ``from . import style as kit``
        names |= set(re.findall(r"from\s+\.\s+import\s+\w+\s+as\s+(\w+)", text))
    if re.search(r"(?:from\s+(?:validation|\.\.?)\s+)?import\s+figures\b(?!\s+as)", text):
        names.add("figures")
    return names


def test_no_private_name_of_the_figures_is_reached_from_outside():
    bad = []
    for p in _python_files():
        text = p.read_text()
        for alias in _aliases(text) | {"figures"}:
            for m in re.finditer(rf"(?<![\w.]){re.escape(alias)}\._[A-Za-z]\w*", text):
                bad.append(f"{p.relative_to(ROOT)}: {m.group(0)}")
        bad += [f"{p.relative_to(ROOT)}: {m.group(0)}"
                for m in re.finditer(r"from\s+validation\.figures(?:\.\w+)?\s+import\s+[^\n]*\b_\w+", text)]
    assert bad == []


def test_no_module_of_the_package_reaches_another_ones_private_name():
    bad = []
    for p in PACKAGE.glob("*.py"):
        text = p.read_text()
        for alias in _aliases(text, inside=True):
            bad += [f"{p.name}: {m.group(0)}" for m in re.finditer(rf"(?<![\w.]){alias}\._[A-Za-z]\w*", text)]
        bad += [f"{p.name}: {m.group(0)}" for m in re.finditer(r"from\s+\.\w*\s+import\s+[^\n]*\b_\w+", text)]
    assert bad == []


def test_the_package_answers_every_former_public_name_and_its_style_kit():
    assert [n for n in FORMER_PUBLIC if not hasattr(figures, n)] == []
    assert [n for n in style.__all__ if getattr(figures, n) is not getattr(style, n)] == []
    assert set(figures.__all__) >= set(FORMER_PUBLIC) | set(style.__all__)


CASE1 = {"masses": [0.815, 3.099], "springs": [41.5, 138.0, 157.8], "walls": "both"}


def test_modal_content_of_a_single_mode_start():
    model = rk4h.make_model("chain", CASE1)
    omega, phi = model.modes()
    k = int(np.argmin(omega))
    q0 = 0.005 * phi[:, k] / np.max(np.abs(phi[:, k]))
    t = np.linspace(0.0, 5.0, 501)
    y = modal_solution(model, model.state(list(q0)))(t)
    c = execute.modal_content(model, t, y)
    np.testing.assert_allclose(c["omega"], omega)
    assert c["fraction0"][k] == pytest.approx(1.0, abs=1e-12) and c["fraction0"].sum() == pytest.approx(1.0)
    assert c["share_min"] == pytest.approx(1.0, abs=1e-9) and 0.0 <= c["share_t"] <= 5.0
    # a two-mode start: fractions follow the amplitudes, no share over the run
    c2 = execute.modal_content(model, t, modal_solution(model, model.state([0.005, 0.0]))(t))
    assert 0.01 < c2["fraction0"].min() and math.isnan(c2["share_min"]) and math.isnan(c2["share_t"])


def test_the_figure_record_holds_the_modal_numbers_and_the_job_carries_them(tmp_path):
    from rk4h.validation import measure, plan
    from rk4h.validation.scenes import load_scenes

    scene = load_scenes(["thesis-2dof-case1"])[0]
    (spec,) = [s for s in plan.plan(scene) if s.grid == "figure"]
    rec = records.roundtrip(execute.execute(scene, spec))
    assert rec.ok, rec.message
    model, _ = execute.problem(scene)
    want = execute.modal_content(model, rec.arrays["t"], rec.arrays["y"])
    got = execute.recorded_modal(rec)
    assert set(got) == {"omega", "fraction0", "share_min", "share_t"}
    for key in got:
        np.testing.assert_allclose(got[key], want[key], rtol=0, atol=0)
    res = measure.measure(scene, [spec], {spec.key: rec})
    (job,) = [j for j in res.figures if j.kind == "state"]
    for key in got:
        np.testing.assert_allclose(job.data["modal"][key], want[key], rtol=0, atol=0)


def test_scene_figures_quote_the_recorded_modes_without_an_eigensolve(tmp_path, monkeypatch):
    model = rk4h.make_model("chain", CASE1)
    t = np.linspace(0.0, 20.0, 2001)
    y = modal_solution(model, model.state([0.005, 0.0]))(t)
    modal = execute.modal_content(model, t, y)

    def refuse():
        raise AssertionError("the figures solved an eigenproblem")

    monkeypatch.setattr(model, "modes", refuse)
    seen = []
    monkeypatch.setattr(style, "SAVE_HOOK", lambda fig, path: seen.append((fig, path)))
    out = dict((p.name, s) for p, s in figures.scene_figures(tmp_path, "c", model, t, y, title="c", modal=modal))
    assert "initial energy by mode" in out["c_displacement.png"]
    fig = dict((p.name, f) for f, p in seen)["c_displacement.png"]
    assert len(fig.axes) == 2  # the zoom panel comes from the recorded omega
    assert fig.axes[1].get_xlim()[1] == pytest.approx(3 * 2 * math.pi / float(np.min(modal["omega"])), rel=1e-9)
    # without modal content: one panel, no modal facts (nothing is computed here)
    seen.clear()
    out = dict((p.name, s) for p, s in figures.scene_figures(tmp_path, "d", model, t, y, title="d"))
    assert "mode" not in out["d_displacement.png"]
    assert len(dict((p.name, f) for f, p in seen)["d_displacement.png"].axes) == 1


def test_the_reading_guides_load_without_matplotlib_and_the_drawings_on_first_use():
    """``--no-figures`` loads no drawing stack: the package imports its drawing
    modules (and matplotlib) only when one of their names is used."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "from rk4h.validation.figures import GENERIC_CAPTIONS, Caption\n"
        "import rk4h.validation.report\n"
        "assert GENERIC_CAPTIONS and 'matplotlib' not in sys.modules, sorted(m for m in sys.modules if 'matplotlib' in m)[:3]\n"
        "from rk4h.validation import figures as F\n"
        "assert callable(F.work_precision) and F.style.DPI == 120 and 'matplotlib' in sys.modules\n"
        "ns = {}\n"
        "exec('from rk4h.validation.figures import *', ns)\n"
        "assert {'work_precision', 'new_figure', 'slug', 'GENERIC_CAPTIONS', 'scene_figures'} <= set(ns)\n"
        "print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
