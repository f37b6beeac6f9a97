"""mbdk's version as a user asks for it: `mbdk.__version__` and `mbdk --version` give the
installed package's metadata, which is pyproject.toml's version, and every manifest carries
the same (issue 39)."""
import subprocess
import sys
import tomllib
from importlib.metadata import version

import pytest

import mbdk


def test_version_attribute_is_the_package_metadata(root):
    declared = tomllib.loads((root / "pyproject.toml").read_text())["project"]["version"]
    assert mbdk.__version__ == version("mbdk") == declared
    assert mbdk.build_info()["version"] == mbdk.__version__


def test_command_line_prints_the_version_and_exits_0():
    r = subprocess.run([sys.executable, "-m", "mbdk", "--version"], capture_output=True,
                       text=True)
    assert (r.returncode, r.stdout, r.stderr) == (0, f"mbdk {mbdk.__version__}\n", "")


def test_a_misspelt_attribute_is_still_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'versoin'"):
        mbdk.versoin  # noqa: B018
