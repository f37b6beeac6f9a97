"""Meson install script: the kernel's Fortran module files (.mod), which a Fortran program that
`use`s mbdk's modules needs beside libmbdk.a, into <includedir>/mbdk (pkg-config's cflags name
that folder). Meson installs no module files itself; they are the compiler's (gfortran of the
version that built the library), written into the library's private build folder.

Arguments: the private folder, the include folder relative to the prefix."""
import os
import shutil
import sys
from pathlib import Path


def main(private: str, includedir: str) -> int:
    mods = sorted(Path(private).glob("*.mod"))
    if not mods:
        print(f"fortran_modules.py: no .mod files in {private}", file=sys.stderr)
        return 1
    prefix = Path(os.environ["MESON_INSTALL_DESTDIR_PREFIX"])
    dest = prefix / includedir / "mbdk"
    dest.mkdir(parents=True, exist_ok=True)
    for m in mods:
        shutil.copy2(m, dest / m.name)
    if not os.environ.get("MESON_INSTALL_QUIET"):
        print(f"Installing {len(mods)} Fortran module files to {dest}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(*sys.argv[1:]))
