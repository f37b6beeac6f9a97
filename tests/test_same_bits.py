"""Runs whose linear algebra is the kernel's own are the same bits under every OpenBLAS kernel:
the planar scenes' starts (the dense least change of a few rows, mbdk_assembly: in-house
LDL^T; LAPACK's dgelsd orders its sums by the BLAS kernel), what runs from them on paths that
call no BLAS (dopri54's reduced solve, ida's dense SUNDIALS LU), and the dense factorisations
of up to 128 unknowns, which mbdk_lapack routes to mbdk_fixed_order (bdf's Newton matrix on
planar and spatial scenes and on the DAE forms of Bricard's linkage and the flyball governor,
95 and 72 unknowns; the spatial Schur complement and rank tests; trapezoidal_index3's Newton
matrix on a spatial scene: LAPACK's own factorisations of these differ between OpenBLAS's
Prescott and Haswell kernels). A start or a factorisation that differs in its last bits is
enough to change where ida ggl or bdf stops on the A02 loop, next to a flat pose or not at
all. Each kernel in a fresh process (OPENBLAS_CORETYPE; OpenBLAS says which it took with
OPENBLAS_VERBOSE=2, and the case does not apply where it takes none)."""
from __future__ import annotations

import os
import platform
import subprocess
import sys
import textwrap

import pytest

KERNELS = ("Prescott", "Haswell", "Sandybridge")
NAMES = ("a02", "a02_bdf", "three_link_pendulum", "trolley_crane", "four_bar", "bricard",
         "heavy_top", "spatial_double_pendulum", "flyball_governor", "dae")

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
    assert len(first) == len(NAMES) + 2          # (a02_bdf at two tolerances, dae on two)
    for kernel, lines in taken.items():
        assert lines == first, (kernel, lines, first)
