"""rk4h.validation.docs_gen: one command writes every generated document, and the
committed ones under docs/ are what it writes."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rk4h.validation import docs_gen

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def fresh():
    return docs_gen.documents()


@pytest.mark.parametrize("name", sorted(docs_gen.DOCS))
def test_committed_generated_docs_are_current(fresh, name):
    committed = (REPO / "docs" / name).read_text(encoding="utf-8")
    assert committed == fresh[name], f"docs/{name} is stale: run python -m rk4h.validation.docs_gen"


def test_the_registry_covers_every_generated_doc():
    # each generator's own entry point prints one of these; a new one is listed here too
    assert set(docs_gen.DOCS) == {"scene-reference.md", "scene.schema.json", "columns.md", "stability-params.md"}


def test_write_then_check(tmp_path, fresh, capsys):
    assert docs_gen.main(["--check", "--out", str(tmp_path)]) == 1  # all missing
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # --check writes nothing
    err = capsys.readouterr().err
    assert all(f"{tmp_path / n} is stale" in err for n in docs_gen.DOCS), err

    assert docs_gen.main(["--out", str(tmp_path)]) == 0
    assert {p.name: p.read_text(encoding="utf-8") for p in tmp_path.iterdir()} == fresh
    assert docs_gen.main(["--check", "--out", str(tmp_path)]) == 0

    (tmp_path / "columns.md").write_text("edited by hand\n", encoding="utf-8")
    mtime = (tmp_path / "scene.schema.json").stat().st_mtime_ns
    assert docs_gen.stale(tmp_path) == ["columns.md"]
    assert docs_gen.write(tmp_path) == ["columns.md"]  # only the stale one is rewritten
    assert (tmp_path / "columns.md").read_text(encoding="utf-8") == fresh["columns.md"]
    assert (tmp_path / "scene.schema.json").stat().st_mtime_ns == mtime
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(docs_gen.DOCS)  # no temporary left


def test_bad_out_is_one_line_and_exit_2(tmp_path, capsys):
    missing = tmp_path / "nope"
    assert docs_gen.main(["--out", str(missing)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--out" in err and str(missing) in err and "Traceback" not in err
    assert not missing.exists()


def test_python_m_check_on_the_repository():
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    r = subprocess.run([sys.executable, "-m", "rk4h.validation.docs_gen", "--check"], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize("flag, name", [("--markdown", "scene-reference.md"), ("--json-schema", "scene.schema.json")])
def test_the_schema_command_prints_what_docs_gen_writes(fresh, capsys, flag, name):
    from rk4h.validation import scene_schema

    assert scene_schema.main([flag]) == 0
    assert capsys.readouterr().out == fresh[name]


@pytest.mark.parametrize("argv, status", [(["--help"], 0), (["--bogus"], 2)])
def test_both_mains_return_argparse_status(capsys, argv, status):
    """docs_gen and scene_schema read their arguments through one parse
    (rk4h.validation.commandline): --help and bad arguments are a returned
    status, never a raised SystemExit."""
    from rk4h.validation import commandline, scene_schema

    assert docs_gen.main(argv) == status
    assert scene_schema.main(argv) == status
    import argparse

    got = commandline.parse(argparse.ArgumentParser(prog="x"), argv)
    assert got == status
    assert isinstance(commandline.parse(argparse.ArgumentParser(prog="x"), []), argparse.Namespace)
    err = capsys.readouterr().err
    assert "Traceback" not in err and (status == 0 or "unrecognized arguments: --bogus" in err)
