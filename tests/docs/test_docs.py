"""The design notes live in the repository and every reference points at them."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DESIGN = ROOT / "docs" / "design.md"


def project_text_files() -> list[Path]:
    """README, pyproject and every text file under the package, agents, tests and docs."""
    suffixes = {".py", ".md", ".yaml", ".yml", ".toml", ".txt", ".cfg"}
    files = [ROOT / "README.md", ROOT / "pyproject.toml"]
    for folder in ("softhand_env", "agents", "tests", "docs", ".ci"):
        files += [p for p in (ROOT / folder).rglob("*")
                  if p.is_file() and (p.suffix in suffixes or folder == ".ci")]
    return files


def test_design_notes_exist_and_cover_the_sign_choices():
    text = DESIGN.read_text()
    for topic in ("cross_term", "uniform", "printed", "secant", "M_deform_kg", "W_obj/2",
                  "θ_pi = θ_i + (−1)^i θ_obj", "path-dependent"):
        assert topic in text, topic


def test_no_reference_to_a_design_file_outside_the_repository():
    offenders = [str(p.relative_to(ROOT)) for p in project_text_files()
                 if re.search(r"\bDESIGN\.md\b", p.read_text(errors="replace"))]
    assert offenders == []


def test_readme_links_the_design_notes():
    assert "](docs/design.md)" in (ROOT / "README.md").read_text()
