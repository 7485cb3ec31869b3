"""The documentation site (mkdocs.yml: docs/*.md + the API reference from the docstrings) builds
without a single warning, and holds what a reader looks for."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_docs_site_builds_strict_without_warnings(tmp_path):
    site = tmp_path / "site"
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
         "--site-dir", str(site)],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    log = proc.stdout + proc.stderr
    assert proc.returncode == 0, log
    assert "WARNING" not in log, log
    # every page of the nav is there; the API reference is rendered from the docstrings
    for page in ("index.html", "papers/index.html", "figures/index.html", "paper004/index.html"):
        assert (site / page).is_file(), page
    envs = (site / "api/envs/index.html").read_text(encoding="utf-8")
    for text in ("SemRelocEnv", "Version History", "semantic_class", "SemRelocEnvV1", "SemSlamEnvV0"):
        assert text in envs, text
    assert "Acta Electronica Sinica" in (site / "papers/index.html").read_text(encoding="utf-8")
    # every figure in docs/figures is shown on some page and listed with its command
    figures_page = (ROOT / "docs/figures.md").read_text(encoding="utf-8")
    for png in sorted((ROOT / "docs/figures").glob("*.png")):
        assert (site / "figures" / png.name).is_file(), png.name
        listed = png.name in figures_page or (
            png.name.startswith("paper000_fastslam1_") and "`paper000_fastslam1_*.png`" in figures_page
        )
        assert listed, f"{png.name} is not in docs/figures.md"
