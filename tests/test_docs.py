"""The documentation against the package (issue 39): every public name of mbdk.__all__ has its
entry in the API reference, the README's links lead to files that exist, and the examples in the
package's docstrings hold (the documentation build runs them too, as doctests; this runs them
where the documentation is not built)."""
import doctest
import importlib
import re

import pytest

import mbdk

#: the modules whose docstrings carry >>> examples
DOCTESTED = ["mbdk", "mbdk.simulate", "mbdk.ode", "mbdk.ivp", "mbdk.scene_file",
             "mbdk.scene_report", "mbdk.results_io", "mbdk.symbolic", "mbdk.sweep"]


def test_every_public_name_is_in_the_api_reference(root):
    listed = set((root / "docs" / "api" / "index.md").read_text().split())
    assert not set(mbdk.__all__) - listed


def test_the_readme_links_lead_to_files(root):
    links = re.findall(r"\]\(([^)#]+)\)", (root / "README.md").read_text())
    missing = [link for link in links if "://" not in link and not (root / link).exists()]
    assert not missing


def test_every_module_with_examples_is_doctested(root):
    """A module that gains a >>> example joins DOCTESTED."""
    with_examples = set()
    for path in (root / "python" / "mbdk").rglob("*.py"):
        if ">>> " in path.read_text():
            parts = path.relative_to(root / "python").with_suffix("").parts
            with_examples.add(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    assert with_examples == set(DOCTESTED)


@pytest.mark.parametrize("name", DOCTESTED)
def test_docstring_examples(name, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)          # examples that write a file write it here
    module = importlib.import_module(name)
    result = doctest.testmod(module, extraglobs={"mbdk": mbdk}, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
