"""
The index-3 family's spectra
============================

trapezoidal_index3, newmark, hht and generalized_alpha are one compiled stepping routine with
different (beta, gamma, alpha_m, alpha_f) (:mod:`mbdk.alpha_family`). On the undamped oscillator
q'' = -omega^2 q each member's step is a linear map whose eigenvalues give its spectral radius
and numerical damping at Omega = omega h. :mod:`mbdk.spectral` measures them from the kernel's
own steps (a scene of one body on a spring, its samples fitted by Prony's method); the lines are
the closed forms of the family's relations, the dots the compiled steps.
"""
import matplotlib.pyplot as plt
import numpy as np

from mbdk import alpha_family, spectral

MEMBERS = [("trapezoidal_index3", {}), ("newmark", {"newmark_gamma": 0.6, "newmark_beta": 0.3025}),
           ("hht", {"alpha_hht": -0.3}), ("generalized_alpha", {"rho_inf": 0.8}),
           ("generalized_alpha", {"rho_inf": 0.5})]
OMEGA = np.logspace(-1.3, 2, 60)
MEASURED = np.logspace(-1, 2, 7)

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
colours = plt.get_cmap("tab10").colors
print(f"{'member':40s} {'Omega':>7s} {'rho measured':>13s} {'rho closed form':>16s}")
for (method, options), colour in zip(MEMBERS, colours):
    p = alpha_family.parameters(method, **options)
    label = method + "".join(f", {k} = {v:g}" for k, v in options.items())
    closed = np.array([alpha_family.closed_form_properties(p, w) for w in OMEGA])
    ax1.semilogx(OMEGA, closed[:, 0], color=colour, label=label)
    ax2.loglog(OMEGA, np.abs(closed[:, 1]), color=colour)
    for w in MEASURED:
        rho, xi, _period, _cpu = spectral.measured_properties(method, w, **options)
        ax1.semilogx(w, rho, "o", color=colour, mfc="none")
        if np.isfinite(xi) and xi > 1e-12:
            ax2.loglog(w, xi, "o", color=colour, mfc="none")
        if w == MEASURED[-1]:
            print(f"{label:40s} {w:7.1f} {rho:13.6f} {alpha_family.closed_form_properties(p, w)[0]:16.6f}")
        # sphinx_gallery_start_ignore
        assert abs(rho - alpha_family.closed_form_properties(p, w)[0]) < 1e-6, (label, w)
        # sphinx_gallery_end_ignore
ax1.set_xlabel("Omega = omega h")
ax1.set_ylabel("spectral radius")
ax1.legend(fontsize=7, loc="lower left")
ax2.set_xlabel("Omega = omega h")
ax2.set_ylabel("numerical damping ratio")
ax2.set_ylim(1e-6, 1)
fig.tight_layout()

# %%
# The trapezoidal rule keeps every mode at radius 1 (no numerical damping); Newmark with
# gamma > 1/2 damps but drops to first order; HHT and generalized-alpha damp the high
# frequencies to their rho_inf while keeping the low ones nearly undamped and second order.
