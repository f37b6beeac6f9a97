"""One result class for scenes of either body kind (mbdk.SceneResult): the same names give the
same quantities for a planar and a spatial run, checked on the double pendulum, which the two
models integrate alike (its spatial form on spherical joints stays in its plane)."""
import numpy as np
import pytest

import mbdk

#: the energy parts every scene run reports, whatever its bodies
COMMON_PARTS = {"kinetic", "potential_gravity", "potential_springs", "power", "work"}


def _pair():
    planar = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=2.0, every=20)
    sc = mbdk.scene("spatial_double_pendulum")
    for k, b in enumerate(sc.bodies):   # the planar run's assembled start (the file's is rounded)
        x, y, a = planar.q[0, 3 * k:3 * k + 3]
        b.position = np.array([x, y, 0.0])
        b.rotation = mbdk.rotations.from_angles([0.0, 0.0, a], "123")
    return planar, mbdk.simulate(sc, "rk4", h=1e-3, t_end=2.0, every=20)


def test_a_planar_and_a_spatial_run_answer_to_the_same_names():
    planar, spatial = _pair()
    assert type(planar) is type(spatial) is mbdk.SceneResult
    assert (planar.kind, spatial.kind) == ("planar", "spatial")
    assert planar.v.shape == (planar.t.size, 6) and spatial.v.shape == (spatial.t.size, 12)
    for name in ("bar1", "bar2"):
        # the planar body seen in 3D: its centre in z = 0, its rotation about z
        assert np.abs(planar.position(name) - spatial.position(name)).max() < 1e-10
        assert np.abs(planar.orientation(name) - spatial.orientation(name)).max() < 1e-10
        assert np.abs(planar.omega_body(name) - spatial.omega_body(name)).max() < 1e-9
    assert COMMON_PARTS <= set(planar.energy_parts) and set(spatial.energy_parts) == COMMON_PARTS
    for part in COMMON_PARTS:
        assert np.abs(planar.energy_parts[part] - spatial.energy_parts[part]).max() < 1e-9, part
    assert np.abs(planar.energy_balance() - spatial.energy_balance()).max() < 1e-9
    assert planar.residual_names[:2] == spatial.residual_names[:2] == ("position", "velocity")


@pytest.mark.parametrize("name", ["spring_damper_bar", "flyball_governor"])
def test_the_power_is_the_rate_of_the_work(name):
    """energy_parts["power"] (dampers, loads, drivers) against the time derivative of the work
    the run integrated (central differences of the samples: their error, of order dt^2, is what
    the tolerance allows)."""
    r = mbdk.simulate(mbdk.scene(name), "dopri54", rtol=1e-9, atol=1e-11, t_end=0.5,
                      dt_out=1e-3)
    p = r.energy_parts
    rate = np.gradient(p["work"], r.t)
    assert np.abs(p["power"]).max() > 1e-3
    assert np.abs(rate - p["power"])[3:-3].max() < 1e-3 * np.abs(p["power"]).max()


def test_a_spatial_runs_third_residual_is_the_quaternions_norm():
    sc = mbdk.scene("heavy_top")
    sc.quaternion_norm = "none"         # the norm drifts: the residual is not roundoff
    r = mbdk.simulate(sc, "rk4", h=2e-3, t_end=1.0)
    assert r.residual_names == ("position", "velocity", "quaternion_norm")
    p = r.q[:, 3:7]
    drift = np.abs(np.linalg.norm(p, axis=1) - 1.0)
    assert drift.max() > 1e-12
    assert np.abs(r.residuals[:, 2] - drift).max() < 1e-15


def test_a_spatial_run_names_the_reactions_it_does_not_compute():
    r = mbdk.simulate(mbdk.scene("heavy_top"), "rk4", h=1e-3, t_end=0.01)
    assert r.a is None and r.reactions is None and r.multipliers is not None
    with pytest.raises(mbdk.NotApplicableError, match="multipliers"):
        r.reaction(r.joints[0])
