"""A scene as an FMI 3.0 co-simulation FMU (issue 41): `mbdk fmu` / mbdk.export_fmu writes it,
FMPy (an independent FMI importer) validates and runs it. The FMU's binary is the kernel's C
stepper reading the scene's tables (kernel/src/fmi/mbdk_fmi3.c), so its outputs at the
communication points must be simulate's samples bit for bit; an input set from the master must
give the motion of the scene with that load written in; a saved and restored FMU state must
repeat a step exactly; a failing run must return an error with the kernel's message in the
log."""
import subprocess
import sys
import zipfile
from dataclasses import replace

import numpy as np
import pytest

import mbdk
from mbdk.fmu import export_fmu
from mbdk.scene import Force

fmpy = pytest.importorskip("fmpy", reason="FMPy validates and runs the FMUs (pip install fmpy)")
from fmpy import read_model_description, simulate_fmu  # noqa: E402
from fmpy.fmi3 import FMU3Slave  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402


def state_names(sc):
    """The FMU's state outputs in the kernel's order (mbdk.fmu's naming)."""
    if sc.kind == "spatial":
        orient = ["p0", "p1", "p2", "p3"] if sc.rotation == "quaternion" else \
            ["angle1", "angle2", "angle3"]
        q = [f"{b.name}.{c}" for b in sc.bodies for c in ["x", "y", "z", *orient]]
        v = [f"{b.name}.{c}" for b in sc.bodies for c in ["vx", "vy", "vz", "wx", "wy", "wz"]]
    else:
        q = [f"{b.name}.{c}" for b in sc.bodies for c in ["x", "y", "angle"]]
        v = [f"{b.name}.{c}" for b in sc.bodies for c in ["vx", "vy", "omega"]]
    return q + v + [f"{w.name}.volume" for w in sc.wear]


def simulate_state(r, sc):
    return np.column_stack([r.q, r.v, *[r.wear[w.name] for w in sc.wear]])


#: every built-in scene: (method, formulation, h, communication step (a multiple of h), t_end),
#: steps inside each scene's stability limit (the gears' mesh, the governor's fast mode)
SCENES = {
    "double_pendulum": ("rk4", "projection", 1e-3, 0.01, 0.2),
    "four_bar": ("rk4", "reduced", 1e-3, 0.01, 0.2),
    "parallelogram_redundant": ("trapezoidal_index3", "augmented_lagrangian", 1e-3, 0.01, 0.2),
    "particle_in_ring": ("rk4", "baumgarte", 1e-3, 0.01, 0.2),
    "physical_pendulum": ("rk4", "reduced", 1e-3, 0.02, 0.2),
    "pla_gears": ("rk4", "reduced", 1e-5, 1e-3, 0.01),
    "spring_bar": ("euler_cromer", "reduced", 1e-3, 0.01, 0.2),
    "spring_damper_bar": ("rk4", "penalty", 1e-3, 0.01, 0.2),
    "three_link_pendulum": ("trapezoidal_index3", "index3", 1e-3, 0.01, 0.2),
    "trolley_crane": ("generalized_alpha", "augmented_lagrangian", 1e-3, 0.01, 0.2),
    "bricard": ("rk4", "projection", 1e-3, 0.01, 0.2),
    "flyball_governor": ("rk4", "reduced", 1e-4, 1e-3, 0.05),
    "free_body": ("rk4", "reduced", 1e-3, 0.01, 0.2),
    "heavy_top": ("rk4", "projection", 1e-3, 0.01, 0.2),
    "spatial_double_pendulum": ("trapezoidal_index3", "augmented_lagrangian", 1e-3, 0.01,
                                0.2),
}


def test_every_built_in_scene_has_a_case():
    assert set(SCENES) == set(mbdk.scenes("all"))


@pytest.mark.parametrize("name", sorted(SCENES))
def test_fmpy_validates_and_runs_simulates_bits(tmp_path, name):
    method, formulation, h, dt, t_end = SCENES[name]
    sc = mbdk.scene(name)
    path = export_fmu(sc, tmp_path / f"{name}.fmu", method=method, h=h, formulation=formulation,
                      stop_time=t_end, step_size=dt, bundle=False)
    assert validate_fmu(str(path)) == []
    md = read_model_description(str(path))
    assert md.fmiVersion == "3.0" and md.coSimulation.canGetAndSetFMUstate
    names = state_names(sc)
    out = simulate_fmu(str(path), stop_time=t_end, output_interval=dt, output=names)
    every = round(dt / h)
    r = mbdk.simulate(sc, method, h=h, t_end=t_end, formulation=formulation, every=every)
    fmu = np.column_stack([out[n] for n in names])
    # FMPy counts its communication points its own way: the same times to roundoff (the FMU
    # takes a point within 1e-9 h of the grid on the grid)
    np.testing.assert_allclose(out["time"], r.t, rtol=0, atol=1e-12)
    want = simulate_state(r, sc)
    assert fmu.shape == want.shape
    assert np.array_equal(fmu, want), np.abs(fmu - want).max()


def test_energy_residual_and_reaction_outputs_are_the_runs(tmp_path):
    """The double pendulum by rk4 on the projection formulation: the FMU's energy.total is
    simulate's energy (kinetic + potential) to roundoff, its residuals are at roundoff, and its
    hinge reactions are simulate's (the same multipliers, at the same state)."""
    sc = mbdk.scene("double_pendulum")
    path = export_fmu(sc, tmp_path / "dp.fmu", method="rk4", h=1e-3, formulation="projection",
                      bundle=False)
    joints = [j.name for j in sc.joints]
    reac = [f"{j}.reaction.{c}" for j in joints for c in ("Fx", "Fy", "M")]
    out = simulate_fmu(str(path), stop_time=0.5, output_interval=0.05,
                       output=["energy.total", "residual.position", "residual.velocity", *reac])
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.5, formulation="projection", every=50)
    np.testing.assert_allclose(out["energy.total"], r.energy, rtol=0, atol=1e-12 * abs(r.energy).max())
    assert out["residual.position"].max() < 1e-12 and out["residual.velocity"].max() < 1e-11
    fmu_reac = np.column_stack([out[n] for n in reac]).reshape(len(r.t), len(joints), 3)
    np.testing.assert_allclose(fmu_reac, r.reactions, rtol=1e-10, atol=1e-10)


def _slave(path, name="fmu"):
    md = read_model_description(str(path))
    unzipped = fmpy.extract(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    log = []

    def logger(_env, status, category, message):
        log.append((status, category.decode(), message.decode()))
    fmu = FMU3Slave(guid=md.instantiationToken, unzipDirectory=unzipped,
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate(loggingOn=True, logMessage=logger)
    return fmu, vr, log


def _start(fmu, t0=0.0):
    fmu.enterInitializationMode(startTime=t0)
    fmu.exitInitializationMode()


def _advance(fmu, t, t_to, dt):
    while t < t_to - 1e-12:
        fmu.doStep(currentCommunicationPoint=t, communicationStepSize=dt)
        t = round(t + dt, 12)
    return t


def test_an_input_torque_step_gives_the_scene_with_the_torque_written_in(tmp_path):
    """A torque input on the double pendulum's upper bar. Set to 2 N m at the start, the FMU's
    motion is the scene with that torque written in, bit for bit. Stepped from 0 to 2 N m at
    t = 0.5: to 0.5 it is the scene without a torque, bit for bit; from there the scene with
    the torque written in, restarted at the FMU's state at 0.5, to 1e-12 (a restarted run
    differs from an uninterrupted one by roundoff: 2.4e-15 here without any torque)."""
    base = mbdk.scene("double_pendulum")
    motor = Force(type="torque", name="motor", body1=base.bodies[0].name, torque=0.0)
    sc = replace(base, forces=[*base.forces, motor])
    path = export_fmu(sc, tmp_path / "dpm.fmu", method="rk4", h=1e-3, inputs=["motor"],
                      bundle=False)
    md = read_model_description(str(path))
    assert {v.name: v.causality for v in md.modelVariables}["motor.torque"] == "input"
    names = state_names(sc)
    driven_sc = replace(sc, forces=[*base.forces, replace(motor, torque=2.0)])
    fmu, vr, log = _slave(path, "from_start")
    refs = [vr[n] for n in names]
    _start(fmu)
    fmu.setFloat64([vr["motor.torque"]], [2.0])
    _advance(fmu, 0.0, 0.5, 0.01)
    r2 = mbdk.simulate(driven_sc, "rk4", h=1e-3, t_end=0.5)
    assert np.array_equal(np.array(fmu.getFloat64(refs)), simulate_state(r2, sc)[-1])
    fmu.terminate()
    fmu.freeInstance()

    fmu, vr, log = _slave(path, "step")
    _start(fmu)
    t = _advance(fmu, 0.0, 0.5, 0.01)
    y_half = np.array(fmu.getFloat64(refs))
    r0 = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.5)
    assert np.array_equal(y_half, simulate_state(r0, sc)[-1])
    fmu.setFloat64([vr["motor.torque"]], [2.0])
    t = _advance(fmu, t, 1.0, 0.01)
    y_end = np.array(fmu.getFloat64(refs))
    fmu.terminate()
    fmu.freeInstance()
    # the scene with the torque written in, from the FMU's state at 0.5
    nb = len(sc.bodies)
    q, v = y_half[:3 * nb].reshape(nb, 3), y_half[3 * nb:].reshape(nb, 3)
    bodies = [replace(b, x=q[k, 0], y=q[k, 1], angle=q[k, 2], vx=v[k, 0], vy=v[k, 1],
                      omega=v[k, 2]) for k, b in enumerate(sc.bodies)]
    driven = replace(sc, bodies=bodies, forces=[*base.forces, replace(motor, torque=2.0)])
    r1 = mbdk.simulate(driven, "rk4", h=1e-3, t0=0.5, t_end=1.0, assemble_initial=False)
    assert driven.forces[-1].torque == 2.0
    np.testing.assert_allclose(y_end, simulate_state(r1, sc)[-1], rtol=0, atol=1e-12)
    # the torque did something: not the free swing's end
    r_free = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0)
    assert np.abs(y_end - simulate_state(r_free, sc)[-1]).max() > 1e-3


@pytest.mark.parametrize("name, method, formulation", [
    ("four_bar", "rk4", "projection"),
    ("trolley_crane", "trapezoidal_index3", "augmented_lagrangian"),
    ("heavy_top", "generalized_alpha", "augmented_lagrangian"),
])
def test_a_rolled_back_step_repeats_bit_for_bit(tmp_path, name, method, formulation):
    """fmi3GetFMUState at 0.3, steps to 0.6, fmi3SetFMUState: the FMU is back at 0.3 with the
    state it had, and the same steps end on the same bits (the index-3 family reuses Newton
    factors across steps: they are part of the saved state)."""
    sc = mbdk.scene(name)
    path = export_fmu(sc, tmp_path / f"{name}.fmu", method=method, h=1e-3,
                      formulation=formulation, bundle=False)
    fmu, vr, _log = _slave(path)
    refs = [vr[n] for n in state_names(sc)]
    _start(fmu)
    t = _advance(fmu, 0.0, 0.3, 0.01)
    y_saved = np.array(fmu.getFloat64(refs))
    state = fmu.getFMUState()
    _advance(fmu, t, 0.6, 0.01)
    first = np.array(fmu.getFloat64(refs))
    assert not np.array_equal(first, y_saved)
    fmu.setFMUState(state)
    assert fmu.getFloat64([vr["time"]])[0] == 0.3
    assert np.array_equal(np.array(fmu.getFloat64(refs)), y_saved)
    _advance(fmu, t, 0.6, 0.01)
    again = np.array(fmu.getFloat64(refs))
    assert np.array_equal(again, first)
    fmu.freeFMUState(state)
    fmu.terminate()
    fmu.freeInstance()


def test_a_parameter_set_before_initialisation_is_the_scene_with_that_value(tmp_path):
    """The trolley crane's spring stiffness and the bar's mass set as parameters: the FMU's
    motion is the scene's with those values written in, bit for bit; a parameter set after
    initialisation is refused by name."""
    sc = mbdk.scene("trolley_crane")
    path = export_fmu(sc, tmp_path / "tc.fmu", method="rk4", h=1e-3, bundle=False)
    fmu, vr, log = _slave(path)
    fmu.setFloat64([vr["spring_and_damper.stiffness"], vr["bar.mass"]], [1500.0, 2.0])
    _start(fmu)
    _advance(fmu, 0.0, 0.2, 0.01)
    refs = [vr[n] for n in state_names(sc)]
    y = np.array(fmu.getFloat64(refs))
    with pytest.raises(fmpy.fmi1.FMICallException):
        fmu.setFloat64([vr["bar.mass"]], [3.0])
    assert any("fixed parameter" in m for _s, _c, m in log)
    fmu.terminate()
    fmu.freeInstance()
    forces = [replace(f, stiffness=1500.0) if f.name == "spring_and_damper" else f
              for f in sc.forces]
    bodies = [replace(b, mass=2.0) if b.name == "bar" else b for b in sc.bodies]
    r = mbdk.simulate(replace(sc, forces=forces, bodies=bodies), "rk4", h=1e-3, t_end=0.2)
    assert np.array_equal(y, simulate_state(r, sc)[-1])
    r0 = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.2)
    assert not np.array_equal(y, simulate_state(r0, sc)[-1])


def test_a_failing_run_is_an_error_with_the_kernels_message(tmp_path):
    """Explicit Euler's drift on the double pendulum (h = 0.05): the watch stops the kernel,
    doStep returns fmi3Error, the log names the status and the watch's finding, the last good
    state stays readable (simulate's state at that time, unwatched, bit for bit), and the next
    doStep is refused. The stepper's watch checks every watch.every steps (16); simulate's
    whole-interval run checks at its samples too, so it stops at most that many steps
    earlier."""
    sc = mbdk.scene("double_pendulum")
    path = export_fmu(sc, tmp_path / "drift.fmu", method="explicit_euler", h=0.05,
                      bundle=False)
    fmu, vr, log = _slave(path)
    _start(fmu)
    t, failed = 0.0, False
    while t < 20.0:
        try:
            fmu.doStep(currentCommunicationPoint=t, communicationStepSize=0.05)
        except fmpy.fmi1.FMICallException:
            failed = True
            break
        t = round(t + 0.05, 12)
    assert failed
    text = "\n".join(m for _s, _c, m in log)
    assert "MBDK_ERR_CONSTRAINT_DRIFT" in text and "the watch: position" in text
    r = mbdk.simulate(sc, "explicit_euler", h=0.05, t_end=20.0, raise_on_failure=False)
    assert not r.success
    t_good = fmu.getFloat64([vr["time"]])[0]
    assert r.t[-1] <= t_good <= r.t[-1] + mbdk.Watch().every * 0.05
    free = mbdk.simulate(sc, "explicit_euler", h=0.05, t_end=t_good, watch=False)
    refs = [vr[n] for n in state_names(sc)]
    assert np.array_equal(np.array(fmu.getFloat64(refs)), simulate_state(free, sc)[-1])
    with pytest.raises(fmpy.fmi1.FMICallException):
        fmu.doStep(currentCommunicationPoint=t_good, communicationStepSize=0.05)
    fmu.freeInstance()


@pytest.mark.parametrize("kw, words", [
    (dict(method="dopri54", rtol=1e-6, atol=1e-8), ["dopri54", "fixed step"]),
    (dict(method="ida", rtol=1e-6, atol=1e-8), ["ida", "whole interval"]),
    (dict(method="rk4", h=1e-3, inputs=["no_such"]), ["no force element", "no_such"]),
    (dict(method="rk4", h=1e-3, inputs=["spring_and_damper"]), ["only point forces",
                                                                "spring_and_damper"]),
    (dict(method="rk4", h=1e-3, inputs=["spring_and_damper.stiffness"]), ["only point forces"]),
    (dict(method="rk4", h=1e-3, no_such_option=1), ["no_such_option", "simulate"]),
])
def test_what_an_fmu_cannot_be_is_refused_by_name(tmp_path, kw, words):
    with pytest.raises(mbdk.InvalidInputError) as e:
        export_fmu("trolley_crane", tmp_path / "x.fmu", bundle=False, **kw)
    for w in words:
        assert w in str(e.value)
    assert not (tmp_path / "x.fmu").exists()


def test_a_bundled_fmu_carries_every_library_its_binary_needs(tmp_path):
    """bundle=True: the binary and every library it loads beyond the C library are in the
    FMU, and the loader finds them there (RPATH $ORIGIN): ldd resolves each into the FMU's
    binaries folder."""
    path = export_fmu("double_pendulum", tmp_path / "dp.fmu", method="rk4", h=1e-3)
    with zipfile.ZipFile(path) as z:
        z.extractall(tmp_path / "x")
    folder = tmp_path / "x" / "binaries" / "x86_64-linux"
    libs = sorted(p.name for p in folder.iterdir())
    assert "double_pendulum.so" in libs and any(n.startswith("libgfortran") for n in libs)
    out = subprocess.run(["ldd", str(folder / "double_pendulum.so")], capture_output=True,
                         text=True, check=True).stdout
    for line in out.splitlines():
        name, arrow, where = line.strip().partition(" => ")
        if arrow and name in libs:
            assert where.startswith(str(folder)), line
    assert validate_fmu(str(path)) == []


def test_the_command_line_writes_the_fmu(tmp_path, root):
    out = tmp_path / "fb.fmu"
    run = subprocess.run([sys.executable, "-m", "mbdk", "fmu", "four_bar", "--method", "rk4",
                          "--h", "1e-3", "--no-bundle", "--out", str(out)],
                         capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "four_bar" in run.stdout and out.exists()
    assert validate_fmu(str(out)) == []


def test_a_driven_load_does_not_trip_the_momentum_watch(tmp_path):
    """A free puck (no joints, no gravity) with a point force that starts at zero: at
    initialisation the watch finds its momentum conserved; once the master pushes it, the
    watch must not stop the run for a momentum drift, and the puck's velocity is F t / m (rk4
    is exact for a constant force)."""
    from mbdk.scene import Body
    sc = mbdk.Scene(name="puck", bodies=[Body("puck", mass=2.0, inertia=0.1)],
                    forces=[Force(type="point_force", name="push", body1="puck",
                                  force=(0.0, 0.0))])
    path = export_fmu(sc, tmp_path / "puck.fmu", method="rk4", h=1e-3, inputs=["push"],
                      bundle=False)
    fmu, vr, log = _slave(path)
    _start(fmu)
    fmu.setFloat64([vr["push.force.x"]], [3.0])
    _advance(fmu, 0.0, 1.0, 0.01)
    vx = fmu.getFloat64([vr["puck.vx"]])[0]
    assert abs(vx - 3.0 * 1.0 / 2.0) < 1e-12, log
    fmu.terminate()
    fmu.freeInstance()


def test_reset_restores_the_exported_step(tmp_path):
    """fmi3Reset after a run with another step: the step reads its exported value again and
    the FMU runs simulate's bits with it."""
    sc = mbdk.scene("four_bar")
    path = export_fmu(sc, tmp_path / "fb.fmu", method="rk4", h=1e-3, bundle=False)
    fmu, vr, _log = _slave(path)
    fmu.setFloat64([vr["step"]], [5e-4])
    _start(fmu)
    _advance(fmu, 0.0, 0.1, 0.01)
    fmu.reset()
    assert fmu.getFloat64([vr["step"]])[0] == 1e-3
    _start(fmu)
    _advance(fmu, 0.0, 0.1, 0.01)
    refs = [vr[n] for n in state_names(sc)]
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1)
    assert np.array_equal(np.array(fmu.getFloat64(refs)), simulate_state(r, sc)[-1])
    fmu.terminate()
    fmu.freeInstance()
