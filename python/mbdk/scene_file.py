"""Scene files: TOML -> dicts -> a Scene of either body kind, and the built-in scenes.

>>> sc = mbdk.scene("double_pendulum")        # or mbdk.load_scene("my_scene.toml")
>>> sc.kind                                   # "planar" or "spatial", by its bodies
'planar'

A file whose bodies say kind = "spatial" is read by python/mbdk/spatial_file.py (its docstring
gives that format), any other by python/mbdk/planar_file.py (likewise). checked() runs the
reader's checks again on a Scene changed in Python after it was read.
"""
from __future__ import annotations

import os
import stat
import tomllib
from pathlib import Path

from .checks import MAX_SCENE_BYTES, show
from .errors import InvalidInputError, NotApplicableError
from .planar_file import checked_planar, planar_scene_from_dict, planar_scene_to_dict
from .scene import Scene, SceneError, SpatialBody, body_kind
from .spatial_file import is_spatial, spatial_scene_from_dict, validate_spatial


def scene_from_dict(data: dict, source: str = "<dict>") -> Scene:
    """Builds and checks a Scene from the parsed TOML structure: a spatial scene where a body
    says kind = "spatial" (the spatial reader names a joint or a body of the other kind), else
    a planar one."""
    if not isinstance(data, dict):
        raise SceneError(f"{source}: a scene is a table")
    if is_spatial(data):
        return spatial_scene_from_dict(data, source)
    return planar_scene_from_dict(data, source)


def scene_to_dict(sc: Scene) -> dict:
    """A planar scene as the parsed TOML structure scene_from_dict takes (its inverse)."""
    if sc.kind == "spatial":
        raise NotApplicableError(f"scene {sc.name!r}: spatial scenes have no writer yet; "
                                 "scene_to_dict writes planar ones")
    return planar_scene_to_dict(sc)


def checked(sc: Scene) -> Scene:
    """The scene with the reader's checks run again: a Scene whose fields were changed in Python
    after it was read (or built by hand) gets the errors a file would, naming the element and
    field, instead of failing somewhere inside the pipeline. A planar scene is re-read (unless
    unchanged since the reader made it); a spatial one is checked in place (a body of the other
    kind among them is named)."""
    if not isinstance(sc, Scene):
        raise SceneError(f"scene must be an mbdk Scene, got {type(sc).__name__}")
    if not isinstance(sc.bodies, list) or not isinstance(sc.joints, list) or \
            not isinstance(sc.forces, list) or not isinstance(sc.wear, list):
        raise SceneError(f"{sc.source}: bodies, joints, forces and wear must be lists")
    for k, b in enumerate(sc.bodies):
        if body_kind(b) is None:
            raise SceneError(f"{sc.source}: body #{k + 1} = {show(b)} is not a body (an mbdk "
                             "Body or SpatialBody)")
    if any(isinstance(b, SpatialBody) for b in sc.bodies):
        validate_spatial(sc)
        return sc
    return checked_planar(sc, scene_from_dict)


def read_scene_bytes(path) -> bytes:
    """A scene file's bytes: a regular file (a device such as /dev/zero, a pipe or a directory
    is refused before it is opened: reading one may never end) of at most MAX_SCENE_BYTES."""
    if not isinstance(path, (str, os.PathLike)):
        raise SceneError(f"path = {show(path)} must be a file path (a string or a Path)")
    path = Path(path)
    try:
        st = os.stat(path)
    except (OSError, ValueError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        raise SceneError(f"{path}: cannot read the scene file ({why})") from None
    if not stat.S_ISREG(st.st_mode):
        kind = ("a directory" if stat.S_ISDIR(st.st_mode) else
                "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else
                "a pipe" if stat.S_ISFIFO(st.st_mode) else
                "a socket" if stat.S_ISSOCK(st.st_mode) else "not a file")
        raise SceneError(f"{path}: is {kind}, not a regular file; give the path of a scene "
                         "file (TOML)")
    limit = MAX_SCENE_BYTES
    if st.st_size > limit:
        raise SceneError(f"{path}: {st.st_size} bytes, more than a scene file may have "
                         f"({limit // 2**20} MiB); is this the scene file?")
    try:
        with open(path, "rb") as f:
            raw = f.read(limit + 1)   # a file that grew since stat stops at the limit too
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the scene file ({exc.strerror})") from None
    if len(raw) > limit:
        raise SceneError(f"{path}: more than {limit // 2**20} MiB, more than a scene file may "
                         "have; is this the scene file?")
    return raw


def load_scene(path) -> Scene:
    """Reads and checks a scene file (TOML), of planar or of spatial bodies.

    Parameters
    ----------
    path : str or os.PathLike
        The scene file: UTF-8 TOML, at most 64 MiB, a regular file.

    Returns
    -------
    Scene
        Its bodies, joints, forces and wear; ``kind`` is "planar" or "spatial", by its bodies.

    Raises
    ------
    SceneError
        A file that cannot be read or is not a scene: the message names the file, the element,
        the field and its value, and what to change.

    See Also
    --------
    scene : a built-in scene by name.

    Notes
    -----
    The format, every element and field: ``help(mbdk.planar_file)`` for planar bodies,
    ``help(mbdk.spatial_file)`` for spatial ones (a scene whose bodies say ``kind =
    "spatial"``), and the documentation's scene format page.
    """
    raw = read_scene_bytes(path)
    path = Path(path)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise SceneError(f"{path}: line {line}: byte {raw[exc.start]:#04x} at offset {exc.start} "
                         "is not UTF-8 text; TOML scene files are UTF-8") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise SceneError(f"{path}: arrays or tables nested too deep to read; a scene file "
                         "needs at most a few levels") from None
    except ValueError as exc:   # an integer of more digits than Python converts (4300)
        raise SceneError(f"{path}: a number out of range: {exc}; give numbers in SI units "
                         "(magnitude below 1e150)") from None
    return scene_from_dict(data, str(path))


SCENE_DIR = Path(__file__).resolve().parent / "scenes"


def scenes(kind: str = "planar") -> list[str]:
    """Names of the built-in scenes of a kind: "planar" (``python/mbdk/scenes/*.toml``),
    "spatial" (``python/mbdk/scenes/spatial/*.toml``) or "all"."""
    dirs = {"planar": [SCENE_DIR], "spatial": [SCENE_DIR / "spatial"],
            "all": [SCENE_DIR, SCENE_DIR / "spatial"]}
    if not isinstance(kind, str) or kind not in dirs:
        raise InvalidInputError(f"kind = {show(kind)}; known: {', '.join(dirs)}")
    return sorted(p.stem for d in dirs[kind] for p in d.glob("*.toml"))


def scene_or_file(arg):
    """A built-in scene by name, or a scene file (of planar or of spatial bodies): what the
    command line and sweeps take."""
    if not isinstance(arg, (str, Path)):
        raise SceneError(f"scene = {show(arg)} must be a built-in scene's name or a scene "
                         "file's path")
    path = Path(arg)
    if path.suffix == ".toml" or path.exists():
        return load_scene(path)   # spatial or planar, by its bodies' kind
    return scene(arg)


def scene(name: str):
    """A built-in scene by name (python/mbdk/scenes/NAME.toml, or scenes/spatial/NAME.toml: a
    scene of spatial bodies).

    Parameters
    ----------
    name : str
        One of ``mbdk.scenes("all")``.

    Returns
    -------
    Scene
        The scene, read as ``load_scene`` reads a file.

    See Also
    --------
    load_scene : your own scene file; its Notes say where the format is described.
    scenes : the built-in scenes' names.

    Examples
    --------
    >>> sc = mbdk.scene("four_bar")
    >>> sc.kind, [b.name for b in sc.bodies]
    ('planar', ['crank', 'coupler', 'rocker'])
    """
    if isinstance(name, str):
        for p in (SCENE_DIR / f"{name}.toml", SCENE_DIR / "spatial" / f"{name}.toml"):
            if p.is_file():
                return load_scene(p)
    raise SceneError(f"no built-in scene {name!r}; built-in scenes: {', '.join(scenes('all'))}")
