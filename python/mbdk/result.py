"""Results of a solve: samples, statistics measured in the kernel, status and a manifest."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import InvalidInputError, NotApplicableError, Status
from .exact import exact_solution
from .options import unpack
from .problems import problems
from .rotations import from_angles, from_quaternion


@dataclass(frozen=True)
class Stats:
    """struct mbdk_stats, counted inside the kernel (kernel/src/core/mbdk_stats.f90; the counters
    SciPy users know keep SciPy's names). cpu_time is the solving thread's CPU time of the
    compiled time loop, wall_time its wall-clock time."""

    steps: int = 0
    nfev: int = 0                  # evaluations of F, finite-difference columns included
    njev: int = 0                  # Jacobian evaluations
    nlu: int = 0                   # factorisations of a Newton matrix (LU or LDL^T)
    newton_iterations: int = 0
    startup_steps: int = 0
    rejected_steps: int = 0        # step-size control: steps rejected by the error test
    newton_failures: int = 0       # steps retried because Newton failed
    order1_steps: int = 0          # bdf, cvode_*: accepted steps at order 1..5
    order2_steps: int = 0
    order3_steps: int = 0
    order4_steps: int = 0
    order5_steps: int = 0          # (cvode_adams: order 5 and above)
    nlu_sparse: int = 0            # of nlu, a DAE method's sparse Newton matrix (bdf, ida)
    cpu_time: float = 0.0
    wall_time: float = 0.0
    t_reached: float = 0.0         # the last accepted step's time (where a failed solve stopped)
    alloc_bytes: float = 0.0       # ERR_NO_MEMORY: the failed allocation's bytes (0: not known)

    @classmethod
    def from_words(cls, words) -> "Stats":
        """From the kernel's struct bytes (8-byte words), field by field by name."""
        # every field comes from the kernel's struct, so the frozen instance is filled directly:
        # the generated __init__ sets each field one by one through object.__setattr__, which
        # cost more than a short solve's kernel call
        stats = object.__new__(cls)
        stats.__dict__.update(unpack("mbdk_stats", words))
        return stats


class Result:
    """What every solve returns (solve_ode: ODEResult, simulate: SceneResult): samples t and the
    state y (one row per sample), stats, status, message, manifest; success is False only when
    the caller asked for failures as results (raise_on_failure=False), and then the samples are
    those written before the failure."""

    @property
    def success(self) -> bool:
        return not self.status.failed

    @property
    def cpu_time(self) -> float:
        """CPU seconds of the solving thread in the compiled time loop."""
        return self.stats.cpu_time

    @property
    def wall_time(self) -> float:
        return self.stats.wall_time


@dataclass
class ODEResult(Result):
    """t (nsamp,), y (nsamp, n): one row per sample (see Result)."""

    t: np.ndarray
    y: np.ndarray
    stats: Stats
    status: Status
    message: str
    manifest: dict = field(default_factory=dict)
    problem: str = ""
    method: str = ""
    params: dict = field(default_factory=dict)
    t0: float = 0.0
    y0: np.ndarray | None = None

    def exact(self) -> np.ndarray | None:
        """The exact solution at the sample times, or None where the problem has none."""
        return exact_solution(self.problem, self.t, self.t0, self.y0, self.params)

    def max_error(self, component: int | None = None) -> float | None:
        """Largest absolute error over the samples (all components, or one), or None."""
        ex = self.exact()
        if ex is None:
            return None
        d = np.abs(self.y - ex)
        return float(np.max(d if component is None else d[:, component]))

    def final_error(self, component: int = 0) -> float | None:
        ex = self.exact()
        return None if ex is None else float(abs(self.y[-1, component] - ex[-1, component]))

    def energy(self) -> np.ndarray | None:
        info = problems().get(self.problem)
        if info is None or info.energy is None:
            return None
        return info.energy(self.y, self.params)


#: what SceneResult.contacts holds per contact, in the kernel's order (mbdk_contact_states)
CONTACT_FIELDS = ("penetration", "penetration_rate", "normal_force", "friction_force")

#: what the three columns of SceneResult.residuals hold, by the scene's body kind
RESIDUAL_NAMES = {"planar": ("position", "velocity", "acceleration"),
                  "spatial": ("position", "velocity", "quaternion_norm")}


@dataclass
class SceneResult(Result):
    """A scene run (see Result), of planar or of spatial bodies: t, the coordinates q and the
    velocities v per sample (y = [q, v]), and the outputs.

    q per body: x, y, angle (planar); the centre and the orientation coordinates, a quaternion
    or the scene's angle set (spatial). v per body: vx, vy, omega (planar); the centre's velocity
    and the body-frame angular velocity (spatial). energy: kinetic + potential per sample;
    energy_parts: "kinetic", "potential_gravity", "potential_springs", "power" (of dampers,
    loads and drivers) and "work" (W, their work as the run integrated it at every step), and
    for planar runs the kernel's breakdown of power and work by element class. residuals
    (nsamp, 3): max |Phi|, max |D v + Phi_t|, and max |D a - gamma| (planar) or max ||p| - 1|
    (spatial): residual_names. An output a run did not compute is None (a planar run computes
    those asked for; a spatial one energy, residuals and multipliers, not a or reactions)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray | None
    multipliers: np.ndarray | None
    reactions: np.ndarray | None   # (nsamp, njoints, 3)
    energy: np.ndarray | None      # kinetic + potential, one per sample
    energy_parts: dict | None
    residuals: np.ndarray | None   # (nsamp, 3): residual_names
    stats: Stats
    status: Status
    message: str
    visits: dict = field(default_factory=dict)
    manifest: dict = field(default_factory=dict)
    assembly: dict = field(default_factory=dict)
    joints: list = field(default_factory=list)
    bodies: list = field(default_factory=list)
    iterations: np.ndarray | None = None   # trapezoidal_index3: Newton iterations per sample
    #: a run the watch stopped: what left its tolerance, where and when (mbdk.watch.drift_report)
    drift: dict | None = None
    #: each wear element's worn volume per sample, by name (integrated with the motion)
    wear: dict = field(default_factory=dict)
    #: the scene's body kind, "planar" or "spatial"
    kind: str = "planar"
    #: spatial: the orientation coordinates (quaternion, euler313, cardan123), and each
    #: sample's angle set where a run switched sets near a lock (switch_angles)
    rotation: str | None = None
    rotations: list | None = None
    #: simulate's events: per event function, the times of its zeros and the states there
    t_events: list | None = None
    y_events: list | None = None
    #: each contact's penetration, its rate, normal force and friction force per sample, by the
    #: contact's name (scenes with contacts, planar and spatial: CONTACT_FIELDS); a gear mesh's
    #: drive flanks under its name, its coast flanks under '<name>.coast'
    contacts: dict = field(default_factory=dict)

    @property
    def y(self) -> np.ndarray:
        """The state [q, v] per sample, as an ODE result has it."""
        return np.hstack([self.q, self.v])

    @property
    def residual_names(self) -> tuple:
        return RESIDUAL_NAMES[self.kind]

    @property
    def q_names(self) -> list[str]:
        """The columns of q, "body.coordinate": x, y, angle (planar); x, y, z and p0..p3 or
        a1..a3 (spatial)."""
        if self.kind == "spatial":
            rot = (["p0", "p1", "p2", "p3"] if self.rotation == "quaternion"
                   else ["a1", "a2", "a3"])
            return [f"{b}.{c}" for b in self.bodies for c in ("x", "y", "z", *rot)]
        return [f"{b}.{c}" for b in self.bodies for c in ("x", "y", "angle")]

    @property
    def v_names(self) -> list[str]:
        """The columns of v: dx, dy, dangle (planar); vx, vy, vz, Wx, Wy, Wz (spatial)."""
        if self.kind == "spatial":
            return [f"{b}.{c}" for b in self.bodies for c in ("vx", "vy", "vz", "Wx", "Wy",
                                                               "Wz")]
        return [f"{b}.d{c}" for b in self.bodies for c in ("x", "y", "angle")]

    def reaction(self, joint: str) -> np.ndarray:
        """(nsamp, 3): Fx, Fy, moment of the named joint on its body1 (planar runs)."""
        if self.reactions is None:
            if self.kind == "spatial":
                raise NotApplicableError("a spatial run does not compute its joints' reactions "
                                         "yet; its multipliers are in result.multipliers")
            raise NotApplicableError("this run did not compute reactions: pass outputs "
                                     "including 'reactions' to simulate")
        if joint not in self.joints:
            raise InvalidInputError(f"joint {joint!r}: the scene has no such joint; its joints "
                                    f"are {', '.join(map(repr, self.joints)) or 'none'}")
        return self.reactions[:, self.joints.index(joint), :]

    def energy_balance(self) -> np.ndarray:
        """E(t) - E(0) - W(t), W = load work + constraint work - damper work as the run
        integrated it at every step (energy_parts["work"]): zero for an exact solution."""
        if self.energy is None:
            raise NotApplicableError("this run did not compute the energy: pass outputs "
                                     "including 'energy' to simulate")
        return self.energy - self.energy[0] - self.energy_parts["work"]

    def _layout(self, body: str) -> tuple[int, int, int]:
        """(the body's first coordinate, its coordinate count, its first velocity)."""
        k = self.bodies.index(body)
        if self.kind == "spatial":
            nqb = 7 if self.rotation == "quaternion" else 6
            return k * nqb, nqb, 6 * k
        return 3 * k, 3, 3 * k

    def position(self, body: str) -> np.ndarray:
        """(nsamp, 3): the body's centre of mass (a planar body's in its plane z = 0)."""
        q0, _nqb, _v0 = self._layout(body)
        if self.kind == "spatial":
            return self.q[:, q0:q0 + 3]
        return np.column_stack([self.q[:, q0:q0 + 2], np.zeros(len(self.t))])

    def orientation(self, body: str) -> np.ndarray:
        """(nsamp, 3, 3): the body's rotation matrix, body to space (a planar body's about z)."""
        q0, nqb, _v0 = self._layout(body)
        if self.kind == "planar":
            c, s = np.cos(self.q[:, q0 + 2]), np.sin(self.q[:, q0 + 2])
            rot = np.zeros((len(self.t), 3, 3))
            rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1] = c, -s, s, c
            rot[:, 2, 2] = 1.0
            return rot
        p = self.q[:, q0 + 3:q0 + nqb]
        if self.rotation == "quaternion":
            return np.array([from_quaternion(x / np.linalg.norm(x)) for x in p])
        sets = self.rotations or [self.rotation] * len(p)
        return np.array([from_angles(x, s[-3:]) for x, s in zip(p, sets)])

    def omega_body(self, body: str) -> np.ndarray:
        """(nsamp, 3): the body's angular velocity in its own frame (a planar body's about z)."""
        _q0, _nqb, v0 = self._layout(body)
        if self.kind == "spatial":
            return self.v[:, v0 + 3:v0 + 6]
        return np.column_stack([np.zeros((len(self.t), 2)), self.v[:, v0 + 2]])


@dataclass
class KernelRun:
    """A scene run as the kernel's entry returned it, before its diagnosis (mbdk.diagnosis):
    the result, whether an interrupt stopped it, the watch's report and the invariants it
    watched (mbdk.watch reads both), the initial state given, and a planar run's tables (as
    built, the values taken from the pose left to the kernel)."""

    result: SceneResult
    interrupted: bool
    watch_report: dict              # mbdk_watch_report_t by name (mbdk.options.unpack)
    invariants: np.ndarray          # (ninv, 7)
    y0: np.ndarray
    tables: object = None


def keep_samples(result: SceneResult, keep) -> SceneResult:
    """The result's samples at the times asked for (keep: their mask among the run's samples,
    which hold t0 and t_end too; None: all), every per-sample output with them."""
    if keep is None:
        return result
    k = np.asarray(keep)[:len(result.t)]
    for name in ("t", "q", "v", "a", "multipliers", "reactions", "energy", "residuals",
                 "iterations"):
        value = getattr(result, name)
        if value is not None:
            setattr(result, name, value[k])
    if result.energy_parts:
        result.energy_parts = {n: v[k] for n, v in result.energy_parts.items()}
    result.wear = {n: v[k] for n, v in result.wear.items()}
    result.contacts = {n: {f: v[k] for f, v in c.items()} for n, c in result.contacts.items()}
    if result.rotations is not None:
        result.rotations = [r for r, kept in zip(result.rotations, k) if kept]
    return result
