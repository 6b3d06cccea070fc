"""The docs extension (``docs/_ext/softhand_docs.py``) makes broken references to this
project's names fail the build and turns Markdown tables of reST docstrings into tables.

Sphinx renders an unresolved ``{py:...}`` reference as plain text unless it runs nitpicky
(which would report every NumPy shape word of the numpy-style type fields). The extension
resolves re-exported names at their defining module and warns on every ``softhand_env.`` /
``agents.`` target that names nothing, has no API entry or goes through a deprecated alias;
``-W`` makes those warnings errors, as in ``.ci/run``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))

PAGE = """# References

```{eval-rst}
.. automodule:: softhand_env.physics.motions
   :members: run_paper_motions
.. automodule:: softhand_env.physics.hand
   :members: PhysicsError
```

Resolved: {py:func}`softhand_env.physics.motions.run_paper_motions`,
{py:mod}`softhand_env.physics.motions`.
Re-export: {py:class}`softhand_env.physics.PhysicsError`.
Stale: {py:class}`agents.loading.ModelPolicy`, {py:func}`softhand_env.physics.no_such_name`.
Undocumented: {py:mod}`softhand_env.physics.kernel`.
Alias: {py:func}`softhand_env.tools.simulate.run_paper_motions`.
Private: {py:class}`softhand_env.envs.dict_obs._DictObservation`.
Third party: {py:class}`numpy.ndarray`, {py:class}`N`.
"""


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    src = tmp_path_factory.mktemp("src")
    (src / "conf.py").write_text(
        "import sys\n"
        f"sys.path[:0] = [{str(ROOT)!r}, {str(ROOT / 'docs' / '_ext')!r}]\n"
        "extensions = ['myst_parser', 'sphinx.ext.autodoc', 'sphinx.ext.napoleon',"
        " 'softhand_docs']\n")
    (src / "index.md").write_text(PAGE)
    out = tmp_path_factory.mktemp("out")
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-q", "-E", "-b", "html", str(src),
                           str(out)], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "MPLBACKEND": "Agg"})
    assert proc.returncode == 0, proc.stderr
    return proc.stderr, (out / "index.html").read_text()


def test_broken_references_to_our_names_warn(build):
    warnings, _ = build
    # the page's own references (the documented docstrings name objects this small build
    # does not document, which are reported too)
    lines = [ln for ln in warnings.splitlines()
             if "softhand_docs.own_reference" in ln and "index.md:" in ln]
    flagged = {ln.split(" reference ")[1].split()[0] for ln in lines}
    assert flagged == {"softhand_env.physics.no_such_name", "agents.loading.ModelPolicy",
                       "softhand_env.physics.kernel",
                       "softhand_env.tools.simulate.run_paper_motions"}
    assert any("deprecated alias softhand_env.tools.simulate" in ln for ln in lines)


def test_good_and_reexported_references_link(build):
    _, html = build
    for anchor in ("softhand_env.physics.motions.run_paper_motions",
                   "softhand_env.physics.hand.PhysicsError"):
        assert f'href="#{anchor}"' in html, anchor
    assert "_DictObservation" in html and "numpy.ndarray" in html  # left as text, no warning


def test_locate_gives_the_defining_module():
    from softhand_docs import locate

    obj, canonical = locate("softhand_env.physics.PhysicsError")
    assert canonical == "softhand_env.physics.hand.PhysicsError"
    assert locate("agents.scripted.PaperSequencePolicy")[1] == (
        "agents.scripted.policies.PaperSequencePolicy")
    assert locate("softhand_env.physics.hand.StepStatus.impulse")[1] == (
        "softhand_env.physics.hand.StepStatus.impulse")
    assert locate("agents.loading") is None
    assert locate("softhand_env.physics.no_such_name") is None


def test_pipe_table_becomes_a_list_table_in_its_field():
    from softhand_docs import rst_repairs

    lines = ["Parameters", "----------", "**kwargs", "    Keywords, this table:", "",
             "| Parameter | Range |", "|---|---|", "| `task` | 'none', 'pose' |",
             "| `ch_limit` | \\|x\\| < 1 |", "", "Returns", "-------"]
    rst_repairs(None, "class", "x", None, None, lines)
    assert lines[3:16] == [
        "    Keywords, this table:", "",
        "    .. list-table::", "       :header-rows: 1", "",
        "       * - Parameter", "         - Range",
        "       * - ``task``", "         - 'none', 'pose'",
        "       * - ``ch_limit``", "         - \\|x\\| < 1", "", "Returns"]
