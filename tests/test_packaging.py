"""The three folders install under one import name, ``rk4h``
(pyproject.toml's package-dir): every folder holding an ``__init__.py`` is
a listed package, so a wheel carries all of them."""
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CONFIG = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]


def _installed_name(folder: Path) -> str:
    rel = folder.relative_to(REPO).as_posix()
    for name, base in sorted(CONFIG["package-dir"].items(), key=lambda kv: -len(kv[1])):
        if rel == base or rel.startswith(base + "/"):
            return ".".join([name, *Path(rel).relative_to(base).parts])
    raise AssertionError(f"{rel} is in no mapped folder")


def test_every_package_folder_is_listed():
    folders = [p.parent for top in ("rk4core", "references", "validation") for p in (REPO / top).rglob("__init__.py")
               if "__pycache__" not in p.parts]
    assert len(folders) >= 3
    missing = sorted(_installed_name(f) for f in folders if _installed_name(f) not in CONFIG["packages"])
    assert not missing, f"add to [tool.setuptools] packages: {missing}"


def test_one_import_name():
    assert {name.split(".")[0] for name in CONFIG["packages"]} == {"rk4h"}
    assert CONFIG["package-dir"] == {"rk4h": "rk4core", "rk4h.references": "references",
                                     "rk4h.validation": "validation"}


PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]


def test_metadata_license_is_an_spdx_expression_with_its_file():
    # setuptools deprecates the {text = ...} table and the license classifiers (removal announced
    # for 2027-02-18): the build would then fail
    assert isinstance(PROJECT["license"], str) and PROJECT["license"] == "MIT"
    assert PROJECT["license-files"] == ["LICENSE"] and (REPO / "LICENSE").read_text().startswith("MIT License")
    assert not [c for c in PROJECT["classifiers"] if c.startswith("License ::")]
    requires = tomllib.loads((REPO / "pyproject.toml").read_text())["build-system"]["requires"]
    assert "setuptools>=77" in requires  # the first setuptools that reads an SPDX `license`


def test_metadata_names_authors_classifiers_and_one_version():
    assert PROJECT["authors"] and PROJECT["classifiers"] and "version" in PROJECT
    assert "dynamic" not in PROJECT or "version" not in PROJECT["dynamic"]
    # no public address: no URL is made up, and the README says so
    assert "urls" not in PROJECT
    assert "no public address" in (REPO / "README.md").read_text()
