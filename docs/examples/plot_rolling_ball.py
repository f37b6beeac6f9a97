"""
Contact and friction: a ball launched sliding
=============================================

A solid ball (m = 1 kg, r = 0.1 m, I = 2/5 m r^2) is set on the floor sliding at v0 = 2 m/s
without spin. Coulomb friction mu m g slows its centre, v = v0 - mu g t, and spins it up,
omega r = (5/2) mu g t, until the slip ends at t = 2 v0 / (7 mu g); then it rolls on at
5/7 v0, having lost m v0^2 / 7 to friction (Routh 1905). The contact is a compliant
sphere-on-plane force with regularised Coulomb friction (:doc:`../guide/contacts`), here
integrated by dopri54 under error control.
"""
import tomllib

import matplotlib.pyplot as plt
import numpy as np

import mbdk
from mbdk.scene_file import scene_from_dict

V0, MU, R, G = 2.0, 0.3, 0.1, 9.81
SCENE = f"""
[scene]
name = "sliding_ball"

[[body]]
name = "ball"
kind = "spatial"
mass = 1.0
shape = {{ type = "sphere", radius = {R} }}
position = [0.0, 0.0, {R - 9.81e-6}]       # resting on its static deflection m g / k
velocity = [{V0}, 0.0, 0.0]

[[force]]
type = "gravity"
g = [0.0, 0.0, -{G}]

[[force]]
type = "contact"
name = "floor"
body1 = "ball"
shape1 = {{ type = "sphere", radius = {R} }}
shape2 = {{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
stiffness = 1e6
damping = 2000.0
friction = {{ static = {MU}, dynamic = {MU}, stiction_speed = 1e-3, transition_speed = 2e-3 }}
"""
ball = scene_from_dict(tomllib.loads(SCENE), "sliding_ball")
r = mbdk.simulate(ball, "dopri54", rtol=1e-9, atol=1e-12, t_end=1.0, dt_out=1e-3)

v = r.v[:, 0]
spin = np.einsum("nij,nj->ni", r.orientation("ball"), r.omega_body("ball"))[:, 1] * R
t_roll = 2 * V0 / (7 * MU * G)
lost = r.energy[0] - r.energy[-1]
print(f"{r.stats.steps} steps ({r.stats.rejected_steps} rejected), CPU {1e3 * r.cpu_time:.1f} ms")
print(f"final speed {v[-1]:.6f} m/s against 5/7 v0 = {5 / 7 * V0:.6f} m/s")
print(f"energy lost {lost:.6f} J against m v0^2 / 7 = {V0**2 / 7:.6f} J; "
      f"max |E - E0 - W| = {np.max(np.abs(r.energy_balance())):.1e} J")

fig, ax = plt.subplots(figsize=(7, 4))
ax.plot(r.t, v, label="v, the centre's speed")
ax.plot(r.t, spin, label="omega r")
ax.plot(r.t, np.where(r.t < t_roll, V0 - MU * G * r.t, 5 / 7 * V0), "k:", lw=1,
        label="Coulomb: v0 - mu g t, then 5/7 v0")
ax.axvline(t_roll, color="grey", lw=0.5)
ax.set_xlabel("t (s)")
ax.set_ylabel("m/s")
ax.legend()
fig.tight_layout()
# sphinx_gallery_start_ignore
assert abs(v[-1] - 5 / 7 * V0) < 1e-5 and abs(lost - V0**2 / 7) < 1e-4
# sphinx_gallery_end_ignore
