"""Packaging metadata: PEP 561 markers shipped, CITATION.cff complete."""

from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("semreloc_env", "filters", "agents")


@pytest.mark.parametrize("package", PACKAGES)
def test_py_typed_marker_exists_and_is_package_data(package):
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    assert (ROOT / package / "py.typed").is_file()
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "py.typed" in config["tool"]["setuptools"]["package-data"][package]


def test_citation_cff_cites_the_project_and_the_three_papers_in_full():
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software"
    assert cff["title"].startswith("semreloc") and cff["authors"] and cff["message"]
    config_version = next(
        line.split("=")[1].strip().strip('"')
        for line in (ROOT / "pyproject.toml").read_text().splitlines()
        if line.startswith("version")
    )
    assert str(cff["version"]) == config_version
    refs = cff["references"]
    assert len(refs) == 3
    for ref in refs:
        assert ref["type"] == "article" and ref["title"] and isinstance(ref["year"], int)
        assert ref["authors"] and all(a["family-names"] and a["given-names"] for a in ref["authors"])
    firsts = {ref["authors"][0]["family-names"] for ref in refs}
    assert firsts == {"Jiang", "Wang", "Cui"}


def test_the_data_files_the_code_opens_ship_with_the_packages():
    # a nineteenth tester's: the ACES log lay in tests/data, outside the packages, so a non-editable install's
    # evaluate-relocalizer ran every episode, then failed to find the log and saved nothing
    import glob

    import agents
    from filters.robot_data import ACES_LOG

    tomllib = pytest.importorskip("tomllib")
    patterns = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    for path in (ACES_LOG, Path(agents.SHIPPED_POLICY)):
        assert path.is_file()
        package, *rest = path.resolve().relative_to(ROOT).parts
        assert package in PACKAGES
        # setuptools' globs: "*" does not cross a "/" (a pattern "*.gz" would not ship a file in a subfolder)
        shipped = {f for p in patterns[package] for f in glob.glob(p, root_dir=ROOT / package)}
        assert "/".join(rest) in shipped, path
