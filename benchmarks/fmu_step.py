#!/usr/bin/env python
"""What a co-simulation step of an mbdk FMU costs beyond the kernel's own steps (issue 41).

The double pendulum (rk4, projection, h = 1e-3) and the heavy top (rk4, projection, h = 1e-3)
exported with mbdk.export_fmu and driven by FMPy's FMU3Slave, one doStep per communication
step of k kernel steps (k = 1, 10, 100), the outputs (every state) read after each doStep as a
master reads them; against mbdk.simulate of the same steps (one whole-interval call, every
step kept). Times are the solving thread's CPU time (time.thread_time) and the wall time, best
of three; the per-doStep overhead is (FMU time - simulate's time) / doSteps. FMPy calls through
ctypes: the overhead includes Python's side of each call, which a C or Modelica master does
not pay.

usage: python benchmarks/fmu_step.py [--quick]
"""
import argparse
import tempfile
import time
from pathlib import Path

import mbdk
from mbdk.fmu import export_fmu, state_components

try:
    import fmpy
    from fmpy import read_model_description
    from fmpy.fmi3 import FMU3Slave
except ImportError:                         # pragma: no cover - the benchmark needs FMPy
    raise SystemExit("this benchmark drives the FMU with FMPy: pip install fmpy")


def fmu_run(path, names, t_end, dt):
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    refs = [vr[n] for n in names]
    fmu = FMU3Slave(guid=md.instantiationToken, unzipDirectory=fmpy.extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench")
    fmu.instantiate()
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    n = round(t_end / dt)
    c0, w0 = time.thread_time(), time.perf_counter()
    for k in range(n):
        fmu.doStep(currentCommunicationPoint=k * dt, communicationStepSize=dt)
        fmu.getFloat64(refs)
    w1, c1 = time.perf_counter(), time.thread_time()
    fmu.terminate()
    fmu.freeInstance()
    return c1 - c0, w1 - w0, n


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="shorter runs")
    args = ap.parse_args()
    t_end = 0.5 if args.quick else 2.0
    h = 1e-3
    print(f"mbdk {mbdk.__version__}, FMPy {fmpy.__version__}; t_end = {t_end} s, h = {h}")
    print(f"{'scene':<18} {'k':>4} {'doSteps':>8} {'FMU CPU ms':>11} {'FMU wall ms':>12} "
          f"{'simulate CPU ms':>16} {'overhead us/doStep':>19}")
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("double_pendulum", "heavy_top"):
            sc = mbdk.scene(name)
            path = export_fmu(sc, Path(tmp) / f"{name}.fmu", method="rk4", h=h,
                              formulation="projection", bundle=False)
            names = [name for name, _unit, _text in state_components(sc)]
            sim = min(mbdk.simulate(sc, "rk4", h=h, t_end=t_end,
                                    formulation="projection").cpu_time for _ in range(3))
            for k in (1, 10, 100):
                best = min((fmu_run(path, names, t_end, k * h) for _ in range(3)),
                           key=lambda r: r[0])
                cpu, wall, n = best
                print(f"{name:<18} {k:>4} {n:>8} {1e3 * cpu:>11.2f} {1e3 * wall:>12.2f} "
                      f"{1e3 * sim:>16.2f} {1e6 * (cpu - sim) / n:>19.1f}")


if __name__ == "__main__":
    main()
