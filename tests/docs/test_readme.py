"""The README's commands are the ones CI runs."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def readme_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    return re.findall(r"```bash\n(.+?)\n```", text, flags=re.S)


def test_readme_opens_with_setup_and_test_commands():
    cmds = readme_commands()
    assert len(cmds) >= 2
    main_job, tests = cmds[0], cmds[1]
    for cmd in (main_job, tests):
        assert "python3 -m venv" in cmd and "pip install torch==2.13.0" in cmd
        assert cmd.index("torch==2.13.0") < cmd.index('pip install -e ".[all]"')
    assert tests.endswith("python -m pytest -q")


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    test_cmd = readme_commands()[1].split("&&")[-1].strip()
    last = [ln for ln in ci.splitlines() if ln.strip() and not ln.startswith("#")][-1]
    assert last.strip() == test_cmd
    # CPU torch before the package with its extras (".[all]" or ".[all,ray]": CI adds Ray)
    assert "torch==2.13.0" in ci and ci.index("torch==2.13.0") < ci.index('-e ".[all')
