"""
A spatial scene: the heavy top
==============================

The built-in scene ``heavy_top`` (the book's 5.1) is a symmetric top on a spherical joint at its
tip, tilted 17 degrees and spun at 50 rad/s about its figure axis. Its state is the centre and
the orientation quaternion with the velocity and the body-frame angular velocity; ``rk4`` on the
``projection`` formulation keeps the joint and the quaternion's unit norm after every step.

The figure axis precesses about the vertical and nods (nutation). For a fast top the mean
precession rate is near m g l / (I3 omega3), the gyroscopic estimate; this one, with its
slower spin and a push about a transverse axis, precesses about a tenth faster.
"""
import matplotlib.pyplot as plt
import numpy as np

import mbdk

top = mbdk.scene("heavy_top")
r = mbdk.simulate(top, "rk4", formulation="projection", h=1e-4, t_end=2.0, every=10)
print(f"{r.stats.steps} steps, CPU {1e3 * r.cpu_time:.1f} ms")

axis = r.orientation("top")[:, :, 2]          # the body z axis (the figure axis) in space
tilt = np.degrees(np.arccos(axis[:, 2]))
heading = np.unwrap(np.arctan2(axis[:, 1], axis[:, 0]))

body = top.bodies[0]
m, l = body.mass, np.linalg.norm(body.position)
i3, omega3 = body.inertia[2, 2], r.omega_body("top")[0, 2]
estimate = m * 9.81 * l / (i3 * omega3)
mean_rate = (heading[-1] - heading[0]) / (r.t[-1] - r.t[0])
print(f"mean precession rate {mean_rate:.3f} rad/s; fast-top estimate m g l / (I3 w3) = "
      f"{estimate:.3f} rad/s")
print(f"max |E - E0| = {np.max(np.abs(r.energy_balance())):.1e} J, "
      f"max |Phi| = {np.max(np.abs(r.residuals[:, 0])):.1e} m")

fig, axes = plt.subplots(1, 2, figsize=(10, 4))
axes[0].plot(axis[:, 0], axis[:, 1])
axes[0].set_aspect("equal")
axes[0].set_xlabel("x")
axes[0].set_ylabel("y")
axes[0].set_title("the figure axis' tip seen from above")
axes[1].plot(r.t, tilt)
axes[1].set_xlabel("t (s)")
axes[1].set_ylabel("tilt from the vertical (deg)")
axes[1].set_title("nutation")
fig.tight_layout()

# %%
# The same top is the compiled problem ``heavy_top`` (Euler's equations with gravity about the
# fixed point and the quaternion kinematics); the scene reaches the same motion through its
# joint's constraint forces:

q0 = mbdk.rotations.to_quaternion(body.rotation)
J1 = body.inertia[0, 0] + m * l**2             # about the tip
ode = mbdk.solve_ode("heavy_top", "rk4", h=1e-4, t_end=2.0, every=10,
                     y0=[*q0, *body.omega_body],
                     params=dict(J1=J1, J2=J1, J3=i3, m=m, g=9.81, l=l))
q_scene = r.q[:, 3:7]                          # the top's quaternion, after its centre
print(f"largest difference of the quaternions: {np.max(np.abs(ode.y[:, :4] - q_scene)):.1e}")
# sphinx_gallery_start_ignore
assert np.max(np.abs(ode.y[:, :4] - q_scene)) < 1e-9
assert abs(mean_rate / estimate - 1) < 0.15
# sphinx_gallery_end_ignore
