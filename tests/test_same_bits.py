"""Runs whose linear algebra is the kernel's own are the same bits under every OpenBLAS kernel:
the planar scenes' starts (the dense least change of a few rows, mbdk_assembly: in-house
LDL^T; with redundant joints, a least squares by a QR with column pivoting in one order of
sums, mbdk_fixed_order, where LAPACK's dgelsd orders its sums by the BLAS kernel and gives the
redundant parallelogram another start under each), what runs from them on
paths that call no BLAS (dopri54's reduced solve, ida's dense SUNDIALS LU), and the dense
factorisations of up to 128 unknowns, which mbdk_lapack routes to mbdk_fixed_order (bdf's
Newton matrix on planar and spatial scenes and on the DAE forms of Bricard's linkage and the
flyball governor, 95 and 72 unknowns; the spatial Schur complement and rank tests;
trapezoidal_index3's Newton matrix on a spatial scene: LAPACK's own factorisations of these
differ between OpenBLAS's Prescott and Haswell kernels). A start or a factorisation that
differs in its last bits is enough to change where ida ggl or bdf stops on the A02 loop, next
to a flat pose or not at all. Each kernel in a fresh process (OPENBLAS_CORETYPE; OpenBLAS says
which it took with OPENBLAS_VERBOSE=2, and the case does not apply where it takes none)."""
from __future__ import annotations

import json
import os
import platform
import re
import shlex
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

KERNELS = ("Prescott", "Haswell", "Sandybridge")
NAMES = ("a02", "a02_bdf", "three_link_pendulum", "trolley_crane", "four_bar", "bricard",
         "heavy_top", "spatial_double_pendulum", "flyball_governor", "dae",
         "parallelogram_redundant")

CODE = textwrap.dedent("""
    import hashlib
    import mbdk
    from mbdk.benchmarks import a02_chain

    def digest(*arrays):
        return hashlib.sha256(b"".join(a.tobytes() for a in arrays)).hexdigest()[:16]

    r = mbdk.simulate(a02_chain(1), "ida", formulation="ggl", rtol=1e-6, atol=1e-8, t_end=5,
                      dt_out=0.05, raise_on_failure=False)
    print("a02", r.status.name, r.stats.steps, digest(r.q[0], r.v[0]), digest(r.q, r.v))
    for rtol in (1e-7, 1e-8):
        r = mbdk.simulate(a02_chain(1), "bdf", formulation="i3", rtol=rtol, atol=1e-2 * rtol,
                          t_end=5, dt_out=0.05, raise_on_failure=False)
        print("a02_bdf", r.status.name, r.stats.steps, digest(r.q, r.v))
    for name in ("three_link_pendulum", "trolley_crane"):
        r = mbdk.simulate(mbdk.scene(name), "dopri54", rtol=1e-8, atol=1e-10, t_end=1,
                          dt_out=0.1)
        print(name, r.status.name, r.stats.steps, digest(r.q[0], r.v[0]), digest(r.q, r.v))
    for name, method, kw in (
            ("four_bar", "bdf", dict(formulation="si2", rtol=1e-6, atol=1e-8, t_end=2,
                                     dt_out=0.1)),
            ("bricard", "rk4", dict(h=1e-3, t_end=2, every=100)),
            ("heavy_top", "bdf", dict(rtol=1e-6, atol=1e-8, t_end=1, dt_out=0.1)),
            ("spatial_double_pendulum", "trapezoidal_index3", dict(h=1e-3, t_end=1, every=100)),
            ("flyball_governor", "rk4", dict(h=1e-4, t_end=0.2, every=100))):
        r = mbdk.simulate(mbdk.scene(name), method, **kw)
        print(name, r.status.name, r.stats.steps, digest(r.q[0], r.v[0]), digest(r.q, r.v))
    for method, kw in (("rk4", dict(formulation="penalty", h=1e-3)),
                       ("trapezoidal_index3", dict(formulation="augmented_lagrangian", h=1e-3))):
        r = mbdk.simulate(mbdk.scene("parallelogram_redundant"), method, t_end=1, every=100,
                          **kw)
        print("parallelogram_redundant", method, r.status.name, r.stats.steps,
              digest(r.q[0], r.v[0]), digest(r.q, r.v))
    for name, form, t_end in (("bricard", "i3", 2), ("flyball_governor", "si2", 1)):
        r = mbdk.simulate(mbdk.scene(name), "bdf", formulation=form, rtol=1e-6, atol=1e-8,
                          t_end=t_end, dt_out=0.1)
        print("dae", name, r.status.name, r.stats.steps, digest(r.q, r.v))
""")


def _run(kernel: str) -> list[str] | None:
    env = dict(os.environ, OPENBLAS_CORETYPE=kernel, OPENBLAS_VERBOSE="2")
    out = subprocess.run([sys.executable, "-c", CODE], env=env, capture_output=True, text=True,
                         timeout=600)
    if f"Core: {kernel}" not in out.stdout + out.stderr:
        return None
    assert out.returncode == 0, out.stderr[-2000:]
    return [ln for ln in out.stdout.splitlines() if ln.split()[0] in NAMES]


def test_starts_and_runs_are_the_same_bits_under_every_blas_kernel():
    if platform.machine() not in ("x86_64", "AMD64"):
        pytest.skip("OPENBLAS_CORETYPE names x86-64 kernels")
    results = {k: _run(k) for k in KERNELS}
    taken = {k: v for k, v in results.items() if v is not None}
    if len(taken) < 2:
        pytest.skip("the BLAS did not take two of OpenBLAS's kernels")
    first = next(iter(taken.values()))
    # (a02_bdf at two tolerances, dae on two scenes, the parallelogram by two methods)
    assert len(first) == len(NAMES) + 3
    for kernel, lines in taken.items():
        assert lines == first, (kernel, lines, first)


def _library_matmuls(entry: dict, tmp: Path) -> list[int]:
    """The source lines of entry's file whose MATMUL calls libgfortran with no inline branch,
    from gfortran's tree dump of it compiled with the build's own command (its objects and
    module files written under tmp, not the build's)."""
    args = shlex.split(entry["command"])
    out = args.index("-o")
    args[out + 1] = str(tmp / "x.o")
    args = [a if not a.startswith("-J") else f"-J{tmp}" for a in args]
    args += ["-I" + a[2:] for a in shlex.split(entry["command"]) if a.startswith("-J")]
    args.append("-fdump-tree-original-lineno")
    proc = subprocess.run(args, cwd=entry["directory"], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    (dump,) = tmp.glob("*.original")
    name = re.escape(Path(entry["file"]).name)
    calls, guarded = set(), set()
    for line in dump.read_text().splitlines():
        m = re.search(name + r":(\d+)", line)
        if m is None:
            continue
        if "_gfortran_matmul_r8" in line:
            calls.add(int(m.group(1)))
        if re.search(r"<= (4\.096e\+3|2\.62144e\+5)\)", line):   # 64^2, 64^3: inline below
            guarded.add(int(m.group(1)))
    dump.unlink()
    return sorted(calls - guarded)


def test_the_kernels_matrix_products_are_compiled_inline(tmp_path):
    """libgfortran's MATMUL picks an AVX, AVX2 or AVX-512 variant by CPU at run time, each
    rounding its sums its own way, which no OPENBLAS_CORETYPE shows: the kernel is built with
    -finline-matmul-limit=64 (meson.build), and gfortran then compiles every product inline up
    to that order, except forms it never inlines (transpose(A) times a vector, a product of a
    product, a function's result as an argument). No kernel source may hold one of those: each
    library call in the tree dump of a file that uses MATMUL must sit behind gfortran's size
    test, in the branch taken only above order 64."""
    root = Path(__file__).resolve().parents[1]
    found = sorted((root / "build").glob("cp*/compile_commands.json"))
    if not found:
        pytest.skip("no meson build directory beside the sources (an installed mbdk)")
    entries = [e for e in json.loads(found[0].read_text())
               if "libmbdk" in e["output"] and e["file"].endswith(".f90")
               and "matmul(" in (Path(e["directory"]) / e["file"]).read_text().lower()]
    assert len(entries) >= 10
    unguarded = {}
    for e in entries:
        lines = _library_matmuls(e, tmp_path)
        if lines:
            unguarded[Path(e["file"]).name] = lines
    assert not unguarded, unguarded
