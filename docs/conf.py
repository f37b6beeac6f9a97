"""Sphinx configuration of mbdk's documentation (`bash tools/setup.sh docs` builds it).

The pages are MyST Markdown; the API reference is autodoc over the docstrings (numpydoc's
conventions); the tutorial and the examples are sphinx-gallery scripts that the HTML build runs,
so every table and figure they show is computed by the build; the pages' snippets are doctests
(`sphinx-build -b doctest`).
"""
import os
import shutil
import sys
from pathlib import Path

import mbdk

# An editable install's import hook can be registered twice (its .pth read once through the
# venv's lib and once through the lib64 symlink); the hook's one-entry rebuild cache then
# alternates between the two, and every failed import (autodoc tries each name as a module
# first) runs ninja again, seconds each on a loaded machine. One hook per build folder does.
_hooks = set()
sys.meta_path[:] = [f for f in sys.meta_path if type(f).__name__ != "MesonpyMetaFinder"
                    or not (repr(f) in _hooks or _hooks.add(repr(f)))]

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

project = "mbdk"
author = "the mbdk authors"
copyright = "the mbdk authors"
release = mbdk.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.doctest",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "mbdk_tables",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "examples/README.rst", "tutorial_src/README.rst", "**/*.ipynb",
                    "**/*.py.md5", "**/*.codeobj.json", "**/*.zip"]
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3

# the API reference: the names of mbdk.__all__, each with its docstring
templates_path = ["_templates"]
autosummary_generate = True
autodoc_default_options = {"members": False}
autodoc_typehints = "none"          # numpydoc's Parameters sections carry the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# the pages' snippets are run by `sphinx-build -b doctest`; they run in a scratch folder so
# that files they write (a scene, a result) land nowhere in the tree
doctest_global_setup = """
import os, tempfile
import numpy as np
import mbdk
os.chdir(tempfile.mkdtemp(prefix="mbdk-doctest-"))
"""

# the tutorial and the gallery: each script is run by the HTML build, which fails if one does.
# sphinx-gallery runs a script in the script's own folder, and these write files (a scene, a
# result): they run from a copy under _build, so that a build leaves the sources as they were
GALLERY_SOURCES = HERE / "_build" / "gallery_src"
for folder in ("tutorial_src", "examples"):
    shutil.copytree(HERE / folder, GALLERY_SOURCES / folder, dirs_exist_ok=True)
sphinx_gallery_conf = {
    "examples_dirs": [str(GALLERY_SOURCES / "tutorial_src"), str(GALLERY_SOURCES / "examples")],
    "gallery_dirs": ["tutorial", "auto_examples"],
    "filename_pattern": r".*\.py$",
    "abort_on_example_error": True,
    "run_stale_examples": True,
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "min_reported_time": 1e9,
    "write_computation_times": False,
    "show_signature": False,
    "reset_modules": ("matplotlib",),
    "capture_repr": (),
}

html_theme = "alabaster"
html_title = f"mbdk {release}"
html_theme_options = {
    "description": "a compiled multibody-dynamics kernel for integrator studies",
    "fixed_sidebar": True,
    "page_width": "1180px",
    "sidebar_width": "250px",
    "show_relbars": True,
}
html_sidebars = {"**": ["about.html", "navigation.html", "relations.html", "searchbox.html"]}
html_static_path = []
html_show_sourcelink = False

# no progress bars from solves the build runs
os.environ.setdefault("MBDK_PROGRESS", "0")
