"""Joint coordinates for spatial scenes (``simulate(..., coordinates="joint")``).

The kernel (kernel/src/spatial/mbdk_joint_coords.f90, whose header is the manual) grows a
spanning tree over the scene's joints from the ground, in sweeps over the table in its order:
revolute, prismatic, cylindrical, spherical and fixed joints can carry a body (a turn, a slide,
both, a turn in 3D as a quaternion, or none); the other joints, and any joint between two
bodies already on the tree, are cut, and their rows are kept as constraints on the joint
coordinates. The state is the joints' coordinates and their rates; the tree's joints hold at
every state to roundoff, and the samples are the bodies' absolute states, so that a joint
run's outputs, watch and plots are an absolute run's.

This module asks the kernel for the split (spatial_joint_tree), refuses what the formulation
does not take with a message that names the body, joint or option, and describes the split for
the manifest.
"""
from __future__ import annotations

from . import _kernel
from .errors import InvalidInputError, NotApplicableError, Status
from .scene import GROUND, Scene
from .spatial_model import spatial_tables

#: simulate's coordinates and their codes (enum mbdk_coordinates, mbdk_spatial_options'
#: coordinates)
COORDINATES = {"absolute": 0, "joint": 1}
#: the kernel's kinds of a tree joint (MBDK_TREE_*)
TREE_KINDS = {1: "turn", 2: "slide", 3: "turn and slide", 4: "fixed", 5: "ball"}
#: the joint types that can carry a body on the tree
TREE_JOINTS = ("revolute", "prismatic", "cylindrical", "spherical", "fixed")
#: what the manifest says a joint run solves
JOINT_SOLVE = ("joint coordinates: the projected equations J^T M J theta'' + G^T lambda = "
               "J^T (f - M b) (Cholesky, mbdk_lapack) and, on a closed loop, S = G (J^T M J)^-1 "
               "G^T on the cut rows kept (kernel/src/spatial/mbdk_joint_coords.f90)")


def check_coordinates(coordinates) -> str:
    """simulate's coordinates, a name of COORDINATES."""
    if not isinstance(coordinates, str) or coordinates not in COORDINATES:
        raise InvalidInputError(f"coordinates = {coordinates!r}: give one of "
                                f"{', '.join(map(repr, COORDINATES))}")
    return coordinates


def joint_tree(scene: Scene) -> dict:
    """The kernel's split of a spatial scene's joints: ``tree`` (per body: its name, its tree
    joint, the joint's kind and the parent, "ground" for the root), ``cut`` (the joints left
    over, whose rows constrain the joint coordinates), ``ndof`` and ``missing`` (bodies the
    tree does not reach)."""
    nb, _mass, _inertia, nj, jtype, jbody, _jr, _nf, _ft, _fb, _fr = spatial_tables(scene)
    tjoint, kind, parent, ndof, status = _kernel.spatial_joint_tree(nb, nj, jtype, jbody)
    names = [b.name for b in scene.bodies]
    joints = [j.name for j in scene.joints]
    tree, missing = [], []
    for b in range(nb):
        if tjoint[b] == 0:
            missing.append(names[b])
            continue
        tree.append({"body": names[b], "joint": joints[tjoint[b] - 1],
                     "kind": TREE_KINDS[int(kind[b])],
                     "parent": "ground" if parent[b] == 0 else names[parent[b] - 1]})
    on_tree = {t["joint"] for t in tree}
    return {"tree": tree, "cut": [j for j in joints if j not in on_tree], "ndof": int(ndof),
            "missing": missing, "status": Status(int(status)),
            "ball": any(t["kind"] == "ball" for t in tree)}


def check_joint_run(scene: Scene, method: str, family: str, formulation: str) -> dict:
    """The refusals of a joint run, each naming what to change; the split where it runs."""
    what = f"coordinates='joint' on scene {scene.name!r}"
    if scene.kind != "spatial":
        raise NotApplicableError(f"{what}: joint coordinates are for spatial scenes; a planar "
                                 "scene runs in its bodies' absolute coordinates")
    if family in ("dae_index3", "ida") or formulation in ("i3", "si2"):
        raise NotApplicableError(f"{what} with {method} ({formulation}): joint coordinates "
                                 "integrate an ODE; give an ODE method (rk4, dopri54, bdf, "
                                 "cvode_bdf, ...) on the reduced or baumgarte formulation")
    if formulation not in ("reduced", "baumgarte"):
        raise NotApplicableError(f"{what} with formulation {formulation!r}: joint coordinates "
                                 "keep a loop's cut joints by the reduced or the baumgarte "
                                 "formulation")
    if scene.rotation != "quaternion":
        raise NotApplicableError(f"{what}: its rotation is {scene.rotation!r}; joint "
                                 "coordinates report the bodies' orientations as quaternions "
                                 "(set the scene's rotation = \"quaternion\")")
    if scene.wear:
        raise NotApplicableError(f"{what}: wear element {scene.wear[0].name!r}: joint "
                                 "coordinates carry no wear states; use coordinates='absolute'")
    split = joint_tree(scene)
    if split["missing"]:
        # name a body next to the tree (on a joint to the ground or to a body on the tree):
        # the one whose joint keeps the others off
        on_tree = {GROUND} | {t["body"] for t in split["tree"]}
        body = next((b for b in split["missing"] for j in scene.joints
                     if b in (j.body1, j.body2) and ({j.body1, j.body2} - {b}) & on_tree),
                    split["missing"][0])
        on = [j.name + f" ({j.type})" for j in scene.joints if body in (j.body1, j.body2)]
        raise NotApplicableError(
            f"{what}: body {body!r} hangs on no {', '.join(TREE_JOINTS)} joint that reaches "
            f"the ground ({'its joints: ' + ', '.join(on) if on else 'it has no joint'}; "
            f"{len(split['missing'])} bodies off the tree in all): joint coordinates take the "
            "motions these joints allow; use coordinates='absolute'")
    if split["status"] != Status.SUCCESS:
        raise NotApplicableError(f"{what}: its tree joints are all fixed (no coordinate to "
                                 "integrate)")
    if method == "euler_cromer" and split["ball"]:
        raise NotApplicableError(f"euler_cromer {what}: a spherical joint on the tree turns its "
                                 "body by a quaternion, whose rates are not its angular "
                                 "velocity (Euler-Cromer's layout y = [q, q'] takes turns and "
                                 "slides only); use rk4")
    return split


def describe(split: dict) -> dict:
    """The manifest's account of a joint run's split."""
    return {"tree": [f"{t['body']} on {t['joint']} ({t['kind']}, from {t['parent']})"
                     for t in split["tree"]],
            "cut": split["cut"], "joint_coordinates": split["ndof"]}
