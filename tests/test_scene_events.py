"""Sample times and events on scenes (issue 39, item 2): simulate's t_eval samples an
error-controlled ODE method's dense output at the times asked for, and its events locate the
zeros of g(t, [q, v]) there as mbdk.solve_ivp does, a terminal one ending the run at its time.
References: free fall's closed form t = sqrt(2 d / g); rk4 at h = 1e-5."""
import math

import numpy as np
import pytest

import mbdk
from mbdk.scene_file import scene_from_dict

G = 9.81


def drop():
    """A ball of radius 0.1 m released at rest with its centre 1.1 m above a floor contact."""
    return scene_from_dict({
        "scene": {"name": "drop"},
        "body": [{"name": "ball", "mass": 1.0, "inertia": 0.004, "y": 1.1}],
        "force": [{"type": "gravity", "g": [0, -G]},
                  {"type": "contact", "name": "floor", "body1": "ball",
                   "shape1": {"type": "circle", "radius": 0.1},
                   "shape2": {"type": "line", "point": [0, 0], "normal": [0, 1]},
                   "stiffness": 1e6, "exponent": 1.0, "damping": 0.0}]})


def test_events_of_a_falling_ball_in_closed_form():
    """The centre passes 0.6 m at sqrt(2 * 0.5 / g) and the ball touches (centre at 0.1 m,
    falling: direction -1, terminal) at sqrt(2 * 1.0 / g); the run ends there, its last
    sample the touch, every output with it; the event states are the falling ball's."""
    def half(t, y):
        return y[1] - 0.6

    def touch(t, y):
        return y[1] - 0.1
    touch.terminal = True
    touch.direction = -1
    r = mbdk.simulate(drop(), "dopri54", rtol=1e-10, atol=1e-12, t_end=2.0, dt_out=0.05,
                      events=[half, touch])
    t_half, t_touch = math.sqrt(2 * 0.5 / G), math.sqrt(2 * 1.0 / G)
    assert r.t_events[0] == pytest.approx([t_half], abs=1e-8)
    assert r.t_events[1] == pytest.approx([t_touch], abs=1e-8)
    assert r.y_events[1][0, 1] == pytest.approx(0.1, abs=1e-8)
    assert r.y_events[1][0, 4] == pytest.approx(-G * t_touch, rel=1e-8)   # vy there
    assert r.t[-1] == pytest.approx(t_touch, abs=1e-12) and r.manifest["terminal_event"] == 1
    assert r.energy is not None and len(r.energy) == len(r.t)


def test_direction_filters_the_zeros():
    """Rising through 0.6 never happens before the touch: with direction +1 nothing is found."""
    def rising(t, y):
        return y[1] - 0.6
    rising.direction = 1
    r = mbdk.simulate(drop(), "dopri54", rtol=1e-9, atol=1e-11, t_end=0.4, events=rising)
    assert r.t_events[0].size == 0


def test_t_eval_samples_the_dense_output_on_planar_and_spatial_scenes():
    """The double pendulum at four times from dopri54's dense output agrees with rk4 at
    h = 1e-5 to 1e-9, every output with the samples; the heavy top likewise; an event at a
    given time (g = t - 0.2) gives the state t_eval gives there."""
    sc = mbdk.scene("double_pendulum")
    te = [0.13, 0.5, 0.77, 1.0]
    r = mbdk.simulate(sc, "dopri54", rtol=1e-10, atol=1e-12, t_end=1.0, t_eval=te)
    ref = mbdk.simulate(sc, "rk4", h=1e-5, t_end=1.0, every=1, outputs=())
    idx = [int(round(t / 1e-5)) for t in te]
    assert np.array_equal(r.t, te) and np.abs(r.q - ref.q[idx]).max() < 1e-9
    assert r.multipliers.shape == (4, 4) and r.energy.shape == (4,)
    top = mbdk.scene("heavy_top")
    s = mbdk.simulate(top, "dopri54", rtol=1e-10, atol=1e-12, t_end=0.5, t_eval=[0.2, 0.25])
    e = mbdk.simulate(top, "dopri54", rtol=1e-10, atol=1e-12, t_end=0.5,
                      events=lambda t, y: t - 0.2)
    assert e.t_events[0] == pytest.approx([0.2], abs=1e-12)
    assert np.abs(e.y_events[0][0] - np.concatenate([s.q[0], s.v[0]])).max() < 1e-9


@pytest.mark.parametrize("method, kw", [("ida", {"rtol": 1e-6}), ("rk4", {"h": 1e-3}),
                                        ("trapezoidal_index3", {"h": 1e-3})])
def test_methods_without_a_dense_output_refuse_by_name(method, kw):
    sc = mbdk.scene("double_pendulum")
    with pytest.raises((mbdk.NotApplicableError, mbdk.InvalidInputError), match="t_eval"):
        mbdk.simulate(sc, method, t_end=0.5, t_eval=[0.1, 0.2], **kw)
    with pytest.raises(mbdk.NotApplicableError, match="events"):
        mbdk.simulate(sc, method, t_end=0.5, events=lambda t, y: t - 0.1, **kw)
