"""
Tutorial: a scene from nothing to its convergence table
=======================================================

In about ten minutes: write a scene file for a pendulum, check it, run it, check the run
against the exact solution, and measure how the error falls with the step size and what each
accuracy costs in CPU time. Every number and figure on this page was computed when this page
was built, by the code shown (download it at the bottom and run it yourself).

You need an installed mbdk (:doc:`../installation`): the commands below run in the source
tree with ``.venv/bin/python`` or after ``source .venv/bin/activate``.
"""

# %%
# 1. Write the scene
# ------------------
#
# A scene is a TOML file of bodies, joints and forces in SI units (:doc:`../guide/scene_format`
# lists every element and field). Ours is a uniform bar of 1 kg and 1 m, hinged to the ground at
# its upper end and released from rest at 30 degrees from the vertical. A planar body's
# coordinates are its centroid ``x``, ``y`` and its ``angle`` from the global x axis, so the bar
# hanging 30 degrees off the vertical has ``angle_deg = -60`` and its centroid half a bar length
# from the hinge. Save this text as ``my_pendulum.toml``:

from pathlib import Path

SCENE = """
[scene]
name = "my_pendulum"
description = "a uniform bar hinged at its upper end, released from 30 deg"

[[body]]
name = "bar"
mass = 1.0                               # kg
shape = { type = "bar", length = 1.0 }   # its inertia, m l^2 / 12
x = 0.25                                 # the centroid (m): 0.5 sin 30 deg
y = -0.4330127019                        #                  -0.5 cos 30 deg
angle_deg = -60                          # from the global x axis
given = ["angle", "omega"]               # kept when the initial state is assembled

[[joint]]
name = "hinge"
type = "revolute"
body1 = "bar"
point1 = [-0.5, 0.0]                     # the bar's upper end, in the bar's frame
body2 = "ground"
point2 = [0.0, 0.0]                      # the hinge, in the global frame

[[force]]
type = "gravity"
g = [0.0, -9.81]
"""
Path("my_pendulum.toml").write_text(SCENE)

# %%
# ``given`` says which coordinates the initial assembly must keep: before a run, the kernel
# moves the other coordinates (here ``x`` and ``y``) onto the joints by a Gauss-Newton
# iteration, so a pose written to a few digits still starts exactly on the constraints.
#
# 2. Check it
# -----------
#
# ``mbdk.load_scene`` reads and checks the file: a misspelt field, a missing body or a
# negative mass is a :class:`mbdk.SceneError` naming the file, the element and the field. The
# scene's report counts coordinates, constraint rows and degrees of freedom and classifies each
# joint:

import mbdk

sc = mbdk.load_scene("my_pendulum.toml")
print(mbdk.scene_report(sc))

# %%
# From a shell the same report is ``mbdk check my_pendulum.toml``. A mistake is named, not
# guessed at; here a joint refers to a body the file does not have:

broken = SCENE.replace('body1 = "bar"', 'body1 = "rod"')
Path("broken.toml").write_text(broken)
try:
    mbdk.load_scene("broken.toml")
except mbdk.SceneError as err:
    print(f"{type(err).__name__}: {err}")

# %%
# 3. Run it
# ---------
#
# :func:`mbdk.simulate` runs a scene with any of the kernel's methods and formulations in one
# compiled call. Here the classical Runge-Kutta method, ``rk4``, at a fixed step of 1 ms over
# 5 s, on the ``reduced`` formulation (the constrained equations of motion solved for the
# accelerations at every evaluation, :doc:`../guide/running`):

r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=5.0)
print(f"status {r.status.name}, {r.stats.steps} steps, {len(r.t)} samples, "
      f"CPU {1e3 * r.cpu_time:.3f} ms")
print("q = (x, y, angle) at t = 5 s:", r.q[-1])

# %%
# The run keeps its own account. ``r.residuals`` holds the largest position, velocity and
# acceleration constraint residual at each sample, and ``r.energy_balance()`` is
# E - E0 - W (the energy's change less the work of dampers, loads and drivers; here there
# are none, so it is the energy error):

import numpy as np

print(f"max |Phi| = {np.max(np.abs(r.residuals[:, 0])):.1e} m, "
      f"max |Phi'| = {np.max(np.abs(r.residuals[:, 1])):.1e} m/s")
print(f"max |E - E0 - W| = {np.max(np.abs(r.energy_balance())):.1e} J "
      f"(E0 = {r.energy[0]:.4f} J)")
print(f"the hinge's force on the bar at t = 0: {r.reaction('hinge')[0, :2]} N")

# %%
# While it runs, a watch checks the same quantities against tolerances: a method that drifts
# off the joints or gains energy ends the run with a named error instead of returning a wrong
# answer (:doc:`../guide/hard_cases`).
#
# 4. Check it against the exact solution
# --------------------------------------
#
# The bar's angle from the vertical, phi = angle + 90 deg, obeys
# phi'' = -(3 g / 2 l) sin(phi), whose solution is known in Jacobi's elliptic functions
# (``mbdk.exact.pendulum``, the compiled problem ``pendulum`` of the book's (4.69)):

import matplotlib.pyplot as plt

from mbdk.exact import pendulum

params = {"g": 9.81, "l": 1.0}
phi0 = np.radians(30.0)


def angle_error(result):
    """The largest error of phi over the samples, against the exact solution."""
    exact = pendulum(result.t, 0.0, [phi0, 0.0], params)[:, 0]
    return np.max(np.abs(result.q[:, 2] + np.pi / 2 - exact))


exact = pendulum(r.t, 0.0, [phi0, 0.0], params)[:, 0]
fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
ax1.plot(r.t, np.degrees(r.q[:, 2] + np.pi / 2), label="mbdk, rk4, h = 1 ms")
ax1.plot(r.t[::100], np.degrees(exact[::100]), "o", mfc="none", label="exact")
ax1.set_ylabel("phi (deg)")
ax1.legend(loc="upper right")
ax2.semilogy(r.t[1:], np.abs(r.q[1:, 2] + np.pi / 2 - exact[1:]))
ax2.set_xlabel("t (s)")
ax2.set_ylabel("|error of phi| (rad)")
fig.tight_layout()
print(f"largest error of phi over 5 s: {angle_error(r):.2e} rad")

# %%
# 5. The convergence table
# ------------------------
#
# How does the error fall as the step shrinks, and what does each accuracy cost? Halve the
# step a few times, for ``rk4`` (fourth order) and for ``trapezoidal_index3`` (the index-3 DAE
# integrated directly, second order). The observed order is log2 of the ratio of successive
# errors; ``r.cpu_time`` is the CPU time of the thread that ran the compiled loop.

print(f"{'method':20s} {'h (s)':>9s} {'steps':>6s} {'error (rad)':>12s} {'order':>6s} "
      f"{'CPU (ms)':>9s}")
table = {}
for method, steps in (("rk4", [0.04, 0.02, 0.01, 0.005, 0.0025]),
                      ("trapezoidal_index3", [0.01, 0.005, 0.0025, 0.00125, 0.000625])):
    previous = None
    for h in steps:
        run = mbdk.simulate(sc, method, h=h, t_end=5.0, outputs=())
        err = angle_error(run)
        order = "" if previous is None else f"{np.log2(previous / err):6.2f}"
        print(f"{method:20s} {h:9.2e} {run.stats.steps:6d} {err:12.3e} {order:>6s} "
              f"{1e3 * run.cpu_time:9.3f}")
        table.setdefault(method, []).append((h, err, run.cpu_time))
        previous = err
# sphinx_gallery_start_ignore
# the build fails if the methods stop showing their orders on this scene
for method, nominal in (("rk4", 4), ("trapezoidal_index3", 2)):
    e = np.array([row[1] for row in table[method]])
    assert np.all(np.abs(np.log2(e[:-1] / e[1:]) - nominal) < 0.1), (method, e)
# sphinx_gallery_end_ignore

# %%
# ``outputs=()`` asks only for t, q and v: the default outputs (accelerations, multipliers,
# reactions, energy, residuals) cost time at every sample, and the table needs none of them.
# The orders come out as 4 and 2, so both methods do what they claim on this scene. The same
# data as a work-precision diagram, error against CPU time, says which method is cheaper for an
# accuracy:

fig, ax = plt.subplots(figsize=(6, 4))
for method, rows in table.items():
    h, err, cpu = np.array(rows).T
    ax.loglog(1e3 * cpu, err, "o-", label=method)
ax.set_xlabel("CPU time (ms)")
ax.set_ylabel("largest error of phi (rad)")
ax.legend()
fig.tight_layout()

# %%
# 6. The same from the command line
# ---------------------------------
#
# Every step above has a command: ``mbdk check`` prints the report, ``mbdk run`` runs a scene
# and saves its samples with the manifest (``.npz``, ``.csv`` or ``.h5``), ``mbdk plot`` draws a
# saved run (:doc:`../guide/cli`). In a shell::
#
#     mbdk check my_pendulum.toml
#     mbdk run my_pendulum.toml --method rk4 --h 1e-3 --t-end 5 --out run.npz
#     mbdk plot run.npz            # run.png: coordinates, energy balance, residuals
#
# which is what this does:

from mbdk import cli

cli.main(["run", "my_pendulum.toml", "--method", "rk4", "--h", "1e-3", "--t-end", "5",
          "--out", "run.npz"])

from mbdk.results_io import load_result

saved = load_result("run.npz")      # a SceneResult again
print(np.array_equal(saved.q, r.q), saved.manifest["method"], saved.manifest["version"])

# %%
# The saved samples are the same bits as the run in Python, and the manifest says which
# version, method, step and compiler flags made them.
#
# Where next
# ----------
#
# * Other methods: :doc:`../guide/methods` (``mbdk.methods()`` lists them), error-controlled
#   ones by ``rtol`` and ``atol`` instead of ``h``:
#   ``mbdk.simulate(sc, "dopri54", rtol=1e-8, atol=1e-10, t_end=5, dt_out=0.01)``.
# * Other formulations (``baumgarte``, ``penalty``, ``projection``, the DAE forms):
#   :doc:`../guide/running`.
# * More elements: springs, dampers, drivers, contacts with friction, wear, spatial bodies:
#   :doc:`../guide/scene_format`.
# * Many runs at once, on Dask: :doc:`../guide/sweeps`.
