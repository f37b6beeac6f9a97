"""
Convergence table of the pendulum
=================================

The book's pendulum (4.69), phi'' = -(3 g / 2 l) sin(phi), is a compiled problem with an exact
solution in Jacobi's elliptic functions (``mbdk.exact.pendulum``). Every fixed-step method of the
kernel integrates it over 5 s at a sequence of halved steps; the table gives each method's
largest error over the 5 s, its observed order (log2 of the ratio of successive errors) and the CPU time
of the compiled loop, and the figure the error against the step.
"""
import matplotlib.pyplot as plt
import numpy as np

import mbdk

T_END = 5.0
STEPS = [0.02, 0.01, 0.005, 0.0025, 0.00125]
P = mbdk.problems()["pendulum"]
METHODS = ["explicit_euler", "euler_cromer", "heun", "trapezoidal", "bdf2", "bdf4", "rk4"]

print(f"{'method':15s} {'order':>5s} " + " ".join(f"{h:>10.2e}" for h in STEPS)
      + "   observed order, CPU at the smallest h")
fig, ax = plt.subplots(figsize=(7, 5))
for name in METHODS:
    errors, cpu = [], 0.0
    for h in STEPS:
        r = mbdk.solve_ode("pendulum", name, h=h, t_end=T_END)
        errors.append(np.max(np.abs(r.y[:, 0] - r.exact()[:, 0])))
        cpu = r.cpu_time
    errors = np.array(errors)
    observed = np.log2(errors[-2] / errors[-1])
    print(f"{name:15s} {mbdk.methods()[name].order:5d} "
          + " ".join(f"{e:10.2e}" for e in errors) + f"   {observed:5.2f}, {1e3 * cpu:.3f} ms")
    # sphinx_gallery_start_ignore
    assert abs(observed - mbdk.methods()[name].order) < 0.1, (name, errors)
    # sphinx_gallery_end_ignore
    ax.loglog(STEPS, errors, "o-", label=f"{name} (order {mbdk.methods()[name].order})")
ax.set_xlabel("step h (s)")
ax.set_ylabel("max |phi - exact| over 5 s (rad)")
ax.set_title(f"pendulum (4.69) from phi = {P.y0[0]:g} rad, phi' = {P.y0[1]:g} rad/s")
ax.legend(fontsize=8)
fig.tight_layout()

# %%
# ``r.exact()`` is the exact solution at the run's samples, where the problem has one
# (``mbdk.problems()`` lists the problems, :doc:`../guide/ode` their solutions). The
# book's start-up of the multistep formulas is Runge-Kutta steps, extrapolated so that they
# do not cap bdf4 below its order.
