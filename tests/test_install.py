"""The kernel as an embedder gets it: `meson install` of the library, header and pkg-config file
into a staging prefix, then the C examples built against that installed copy with nothing but
`pkg-config --cflags --libs mbdk` and run (they check their own results; exit code 0 = pass)."""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest


def _tool(name):
    return shutil.which(name, path=str(Path(sys.executable).parent)) or shutil.which(name)


@pytest.mark.parametrize("example", ["c_embedding.c", "c_index3.c", "c_stepper.c",
                                     "c_spatial.c", "c_scene_file.c", "fortran_embedding.f90"])
def test_c_example_builds_against_the_installed_copy(tmp_path, root, example):
    """The C examples, and the Fortran one (its `use mbdk_...` statements read the module
    files installed into includedir/mbdk, which pkg-config's cflags name)."""
    build = root / "build" / f"cp{sys.version_info[0]}{sys.version_info[1]}"
    if not (build / "build.ninja").exists():
        pytest.skip("no meson build folder: mbdk is not an editable install from this tree")
    fortran = example.endswith(".f90")
    compiler = os.environ.get("FC", "gfortran") if fortran else os.environ.get("CC", "cc")
    meson, pkgconf, cc = _tool("meson"), _tool("pkg-config"), _tool(compiler)
    if not (meson and pkgconf and cc):
        pytest.skip("meson, pkg-config or a compiler is missing")
    stage = tmp_path / "stage"
    subprocess.run([meson, "install", "-C", str(build), "--destdir", str(stage), "--tags",
                    "devel"], check=True, capture_output=True, text=True)
    pcs = list(stage.rglob("mbdk.pc"))
    assert len(pcs) == 1 and list(stage.rglob("mbdk.h")) and list(stage.rglob("libmbdk.a"))
    assert list(stage.rglob("mbdk/mbdk_kinds.mod"))
    prefix = re.search(r"^prefix=(.*)$", pcs[0].read_text(), re.M).group(1)
    staged = str(stage) + prefix
    env = {**os.environ, "PKG_CONFIG_PATH": str(pcs[0].parent)}
    flags = subprocess.run([pkgconf, f"--define-variable=prefix={staged}", "--cflags", "--libs",
                            "mbdk"], check=True, capture_output=True, text=True, env=env).stdout
    assert f"-I{staged}/include" in flags and f"-L{staged}" in flags   # the installed copy
    assert f"-I{staged}/include/mbdk" in flags                          # its Fortran modules
    exe = tmp_path / "example"
    subprocess.run([cc, str(root / "kernel" / "examples" / example), *flags.split(), "-o",
                    str(exe)], check=True, capture_output=True, text=True)
    # c_scene_file reads a scene's tables file (meson's own check, on the double pendulum)
    args = (["check", str(root / "kernel" / "examples" / "double_pendulum.tables.toml")]
            if example == "c_scene_file.c" else [])
    run = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=120,
                         cwd=tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
