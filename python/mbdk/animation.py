"""An animation of a scene run from its own samples (issue 39, item 6): a self-contained HTML
page (or fragment) whose <canvas> replays the motion, planar in the plane and spatial in an
orthographic view the reader turns by dragging. Nothing is interpolated or re-integrated: each
frame is one of the run's samples, drawn at the sample's own time, so what plays is what the
run computed (an adaptive run's uneven samples play at their true times).

What is drawn comes from the scene: each body as lines from its centre to the points its
joints and force elements hold (point1/point2 in the body's frame), its contact shapes
(circles, rings, gears' pitch circles), each joint as a dot, ground points as fixed anchors,
and planar springs and dampers as thin lines between their two points; spatial bodies carry a
short triad of their axes, so that a spin about a body's own axis shows. Every world point is
the body's centre plus its rotation matrix times the body point, from SceneResult.position
and SceneResult.orientation (the package's own rotation maths).

The page needs nothing from the network: the player is a few lines of plain JavaScript drawing
on a <canvas>. As it plays it writes the frame it shows and that frame's time to the canvas'
data-frame and data-t attributes (what a headless browser reads to see that it plays).
"""
from __future__ import annotations

import copy
import html
import json
import math
from pathlib import Path

import numpy as np

from .errors import InvalidInputError
from .result import SceneResult, keep_samples
from .results_io import write_atomic
from .scene import GROUND

#: at most this many frames: enough for smooth motion at a few seconds of run, few enough
#: that a page of fifteen scenes stays a few hundred kilobytes
MAX_FRAMES = 240
#: joint types that hold no point (a driver or a coupling acts on coordinates)
POINTLESS = {"driver", "coupling", "angle_driver", "slide_driver"}
#: force types drawn as a line between their two points (planar)
LINE_FORCES = {"spring", "damper", "spring_damper"}
#: points on a drawn circle
CIRCLE_POINTS = 24
#: canvas size in CSS pixels
WIDTH, HEIGHT = 400, 300


def frame_indices(n: int, max_frames: int = MAX_FRAMES) -> np.ndarray:
    """The samples shown, evenly spread over the sample indices, the first and last always
    among them (all of them when there are no more than max_frames)."""
    if n <= max_frames:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, max_frames)).astype(int))


class _Drawing:
    """What is drawn, as points in their owner's frame (a body's, or the ground's = space)."""

    def __init__(self, dim: int):
        self.dim = dim
        self.points: list[tuple[str, np.ndarray]] = []
        self.segments: list[tuple[int, int, int]] = []     # (i, j, style)
        self.dots: list[tuple[int, int]] = []              # (i, style)

    def point(self, owner: str, p) -> int:
        p = np.zeros(3) + np.pad(np.asarray(p, float)[:3], (0, 3 - min(3, len(p))))
        self.points.append((owner, p))
        return len(self.points) - 1


#: styles the player knows (index into its style table): body line, joint link, force line,
#: shape outline, joint dot, ground anchor, body centre, axes x, y, z
BODY, LINK, FORCE, SHAPE, JOINT, ANCHOR, CENTRE, AX, AY, AZ = range(10)


def _circle(d: _Drawing, owner: str, centre, radius: float, spoke: bool) -> None:
    c = np.pad(np.asarray(centre, float)[:2], (0, 1))
    ring = [d.point(owner, c + radius * np.array([math.cos(a), math.sin(a), 0.0]))
            for a in np.linspace(0.0, 2 * math.pi, CIRCLE_POINTS, endpoint=False)]
    d.segments += [(ring[k], ring[(k + 1) % len(ring)], SHAPE) for k in range(len(ring))]
    if spoke:       # a radius, so that a turning circle shows its turn
        d.segments.append((d.point(owner, c), ring[0], SHAPE))


def _shape(d: _Drawing, owner: str, shape: tuple) -> None:
    """A contact shape: circles and rings as circles, a gear as its pitch circle."""
    if not shape:
        return
    kind, centre, size = shape[0], shape[1], shape[2]
    if kind in ("circle", "ring"):
        _circle(d, owner, centre, float(size), spoke=kind == "circle" and owner != GROUND)
    elif kind == "gear":
        teeth, module = size[0], size[1]
        _circle(d, owner, centre, 0.5 * teeth * module, spoke=owner != GROUND)


def drawing(scene) -> _Drawing:
    """The scene's drawn points, lines and dots (module docstring)."""
    spatial = scene.kind == "spatial"
    d = _Drawing(3 if spatial else 2)
    names = [b.name for b in scene.bodies]
    centres = {n: d.point(n, np.zeros(3)) for n in names}
    held = {n: [] for n in names}           # the points each body holds

    def end(owner, p):
        k = d.point(owner, p)
        if owner == GROUND:
            d.dots.append((k, ANCHOR))
        else:
            held[owner].append(k)
        return k

    for j in scene.joints:
        if j.type in POINTLESS:
            continue
        a = end(j.body1, j.point1)
        b = end(j.body2, j.point2)
        d.dots.append((a, JOINT))
        d.segments.append((a, b, LINK))     # zero length where the joint joins two points
    for f in scene.forces:
        if spatial:
            continue        # spatial forces hold their points in the kernel's reals
        if f.type in LINE_FORCES:
            d.segments.append((end(f.body1, f.point1), end(f.body2, f.point2),
                               FORCE))
        elif f.type == "contact":
            _shape(d, f.body1, f.shape1)
            _shape(d, f.body2, f.shape2)
    for n in names:
        d.segments += [(centres[n], k, BODY) for k in held[n]]
        d.dots.append((centres[n], CENTRE))
    if spatial:
        # the body's axes, a tenth of the scene's size long (the player scales nothing)
        size = max([float(np.linalg.norm(p)) for _o, p in d.points] + [0.05])
        for n in names:
            for axis, style in zip(np.eye(3), (AX, AY, AZ)):
                d.segments.append((centres[n], d.point(n, 0.25 * size * axis), style))
    return d


def _check(result, scene, max_frames) -> None:
    if not isinstance(result, SceneResult):
        raise InvalidInputError(f"result: {type(result).__name__} is not a scene run "
                                "(mbdk.simulate's SceneResult)")
    if scene is None or not hasattr(scene, "bodies"):
        raise InvalidInputError(f"scene: {scene!r} is not a scene (mbdk.scene, "
                                "mbdk.load_scene): the drawing needs its joints' points")
    names = [b.name for b in scene.bodies]
    if names != list(result.bodies) or scene.kind != result.kind:
        raise InvalidInputError(f"scene: {scene.name!r} has the {scene.kind} bodies {names}; "
                                f"the result's are {result.kind} {list(result.bodies)}: not "
                                "the scene that was run")
    if isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer)) \
            or max_frames < 2:
        raise InvalidInputError(f"max_frames: {max_frames!r}; give a whole number of at "
                                "least 2 (the first and the last sample)")
    if len(result.t) == 0:
        raise InvalidInputError("result: the run has no samples to animate")


def frames(result: SceneResult, scene, max_frames: int = MAX_FRAMES):
    """(t, xyz, drawing): the shown samples' times (nframes,), every drawn point's world
    coordinates at them (nframes, npoints, 3) and what joins them. Samples whose coordinates
    are not finite (a failed run's) are left out."""
    _check(result, scene, max_frames)
    finite = np.all(np.isfinite(result.q), axis=1) & np.isfinite(result.t)
    if not finite.any():
        raise InvalidInputError("result: no sample has finite coordinates")
    keep = np.zeros(len(result.t), bool)
    keep[np.flatnonzero(finite)[frame_indices(int(finite.sum()), int(max_frames))]] = True
    # the shown samples as a result of their own (a shallow copy: the run is left whole), so
    # that positions and rotation matrices are computed for them only
    shown = keep_samples(copy.copy(result), keep)
    d = drawing(scene)
    xyz = np.empty((len(shown.t), len(d.points), 3))
    centre = {b: shown.position(b) for b in shown.bodies}
    rot = {b: shown.orientation(b) for b in shown.bodies}
    for k, (owner, p) in enumerate(d.points):
        if owner == GROUND:
            xyz[:, k] = p
        else:
            xyz[:, k] = centre[owner] + rot[owner] @ p
    return np.array(shown.t, float), xyz, d


def _up(scene) -> list:
    """The view's up direction: against gravity where the scene has it, else +z (spatial)."""
    for f in scene.forces:
        if f.type == "gravity":
            g = np.asarray(getattr(f, "reals", None) or getattr(f, "g", ()), float)
            if g.size == 3 and np.linalg.norm(g) > 0:
                return (-g / np.linalg.norm(g)).tolist()
    return [0.0, 0.0, 1.0]


def _data(result, scene, max_frames, title) -> dict:
    t, xyz, d = frames(result, scene, max_frames)
    # five significant digits: a pixel is far coarser, and the page stays small
    xyz = xyz[:, :, :d.dim]
    lo, hi = xyz.reshape(-1, d.dim).min(axis=0), xyz.reshape(-1, d.dim).max(axis=0)
    span = float(np.max(hi - lo)) or 1.0
    digits = max(0, 5 - int(math.floor(math.log10(span))))
    # the times in full: each frame plays at its own sample's time, whatever t0 is
    return {"title": title, "dim": d.dim, "t": [float(x) for x in t],
            "xyz": np.round(xyz, digits).reshape(len(t), -1).tolist(),
            "segments": d.segments, "dots": d.dots, "up": _up(scene)}


def animation_html(result: SceneResult, scene, max_frames: int = MAX_FRAMES,
                   title: str | None = None) -> str:
    """The animation as an HTML fragment: its canvas, controls and data. A page that holds
    fragments needs the player once (player_script(); animation_page includes it)."""
    title = scene.name if title is None and hasattr(scene, "name") else (title or "")
    data = _data(result, scene, max_frames, title)
    # JSON inside a <script> element: every "<" as the escape \u003c, so that no value (a title
    # with "</script>" or "<!--") can close or comment out the element
    blob = json.dumps(data, separators=(",", ":")).replace("<", "\\u003c")
    hint = " (drag to turn)" if data["dim"] == 3 else ""
    return (f"<figure class='mbdk-anim' style='margin:0'><canvas width='{WIDTH}' "
            f"height='{HEIGHT}' data-frame='0' data-t='{data['t'][0]}' "
            "style='border:1px solid #ccc;touch-action:none'></canvas>"
            "<div class='mbdk-controls' style='font-size:12px'>"
            "<button type='button' class='play'>pause</button> "
            f"<input type='range' class='slider' min='0' max='{len(data['t']) - 1}' value='0' "
            "style='width:200px;vertical-align:middle'> <span class='time'></span> "
            "<label><input type='checkbox' class='loop' checked> loop</label></div>"
            f"<figcaption>{html.escape(title)}{hint}</figcaption>"
            f"<script type='application/json' class='mbdk-anim-data'>{blob}</script></figure>")


def player_script() -> str:
    """The player: starts every animation of the page (figure.mbdk-anim) playing."""
    return f"<script>{_PLAYER}</script>"


def animation_page(result: SceneResult, scene, max_frames: int = MAX_FRAMES,
                   title: str | None = None) -> str:
    """A whole page holding the animation and its player, working offline."""
    name = title if title is not None else getattr(scene, "name", "")
    m = result.manifest or {}
    run = ", ".join(f"{k} {m[k]}" for k in ("method", "formulation") if m.get(k))
    body = animation_html(result, scene, max_frames, title)
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(name)}"
            "</title></head><body style='font-family:sans-serif'>"
            f"<h1 style='font-size:18px'>{html.escape(name)}</h1>"
            f"<p style='font-size:12px;color:#555'>{html.escape(run)}; t = {result.t[0]:g} .. "
            f"{result.t[-1]:g} s, {len(result.t)} samples</p>{body}{player_script()}"
            "</body></html>\n")


def write_animation(result: SceneResult, scene, path, max_frames: int = MAX_FRAMES,
                    title: str | None = None) -> Path:
    """The animation page written to path (.html), whole or not at all."""
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise InvalidInputError(f"{path}: an animation is an HTML page; give a name ending "
                                "in .html")
    text = animation_page(result, scene, max_frames, title)
    write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    return path


# The player, plain JavaScript. Time runs in real seconds from the play's start: the frame
# shown is the last sample whose t has passed (so uneven samples keep their true timing). A
# 3-D view is an orthographic projection turned by yaw (about the up axis) and pitch.
_PLAYER = r"""
(function(){
var STYLE=[['#1f5fa8',3],['#888',1],['#c07000',1],['#2a8a4a',1],['#000',0],['#555',0],
 ['#1f5fa8',0],['#d33',1.5],['#2a2',1.5],['#33d',1.5]];
function setup(fig){
 var D=JSON.parse(fig.querySelector('.mbdk-anim-data').textContent);
 var cv=fig.querySelector('canvas'),cx=cv.getContext('2d');
 var play=fig.querySelector('.play'),sl=fig.querySelector('.slider');
 var tl=fig.querySelector('.time'),lp=fig.querySelector('.loop');
 var n=D.t.length,np=D.xyz[0].length/D.dim,dim=D.dim,t0=D.t[0],t1=D.t[n-1];
 var up=D.up,yaw=-0.6,pitch=0.35,frame=0,playing=true,start=null,drag=null;
 // a basis whose third vector is up (spatial): the view turns about it
 var e3=up,a=Math.abs(up[0])<0.9?[1,0,0]:[0,1,0];
 function cr(u,v){return[u[1]*v[2]-u[2]*v[1],u[2]*v[0]-u[0]*v[2],u[0]*v[1]-u[1]*v[0]];}
 function nz(u){var l=Math.hypot(u[0],u[1],u[2]);return[u[0]/l,u[1]/l,u[2]/l];}
 var e1=nz(cr(a,e3)),e2=cr(e3,e1);
 function dot(u,v){return u[0]*v[0]+u[1]*v[1]+u[2]*v[2];}
 // the fit: over every frame, a box (planar) or a sphere any view keeps inside (spatial)
 var lo=[1e300,1e300,1e300],hi=[-1e300,-1e300,-1e300];
 for(var f=0;f<n;f++)for(var k=0;k<np;k++)for(var c=0;c<dim;c++){
  var x=D.xyz[f][k*dim+c];if(x<lo[c])lo[c]=x;if(x>hi[c])hi[c]=x;}
 var mid=[],rad=0;for(var c=0;c<dim;c++)mid.push(0.5*(lo[c]+hi[c]));
 for(var f=0;f<n;f++)for(var k=0;k<np;k++){var s=0;for(var c=0;c<dim;c++){
  var d=D.xyz[f][k*dim+c]-mid[c];s+=d*d;}rad=Math.max(rad,Math.sqrt(s));}
 var W=cv.width,H=cv.height,scale;
 if(dim==2){scale=0.9*Math.min(W/Math.max(hi[0]-lo[0],1e-9),H/Math.max(hi[1]-lo[1],1e-9));}
 else scale=0.45*Math.min(W,H)/Math.max(rad,1e-9);
 function project(f,k){
  var o=k*dim,p=D.xyz[f];
  if(dim==2)return[W/2+scale*(p[o]-mid[0]),H/2-scale*(p[o+1]-mid[1])];
  var r=[p[o]-mid[0],p[o+1]-mid[1],p[o+2]-mid[2]];
  var x=dot(r,e1),y=dot(r,e2),z=dot(r,e3),cy=Math.cos(yaw),sy=Math.sin(yaw);
  var u=cy*x-sy*y,w=sy*x+cy*y;            // turned about up, w toward the viewer
  var v=Math.cos(pitch)*z-Math.sin(pitch)*w;
  return[W/2+scale*u,H/2-scale*v];}
 function draw(){
  cx.clearRect(0,0,W,H);cx.lineCap='round';
  if(dim==3){  // the space axes x, y, z (red, green, blue) in the corner: the view's turn
   var o=[30,H-30];[[1,0,0],[0,1,0],[0,0,1]].forEach(function(ax,i){
    var x=dot(ax,e1),y=dot(ax,e2),z=dot(ax,e3),cy=Math.cos(yaw),sy=Math.sin(yaw);
    var u=cy*x-sy*y,w=sy*x+cy*y,v=Math.cos(pitch)*z-Math.sin(pitch)*w,L=20;
    cx.strokeStyle=['#f99','#9c9','#99f'][i];cx.lineWidth=1;cx.beginPath();
    cx.moveTo(o[0],o[1]);cx.lineTo(o[0]+L*u,o[1]-L*v);cx.stroke();});}
  var P=[];for(var k=0;k<np;k++)P.push(project(frame,k));
  D.segments.forEach(function(s){var st=STYLE[s[2]];cx.strokeStyle=st[0];cx.lineWidth=st[1];
   cx.beginPath();cx.moveTo(P[s[0]][0],P[s[0]][1]);cx.lineTo(P[s[1]][0],P[s[1]][1]);
   cx.stroke();});
  D.dots.forEach(function(d){var p=P[d[0]];cx.fillStyle=STYLE[d[1]][0];
   if(d[1]==5){cx.fillRect(p[0]-4,p[1]-4,8,8);}
   else{cx.beginPath();cx.arc(p[0],p[1],d[1]==4?3.5:2.5,0,6.3);cx.fill();}});
  cv.setAttribute('data-frame',frame);cv.setAttribute('data-t',D.t[frame]);
  sl.value=frame;tl.textContent='t = '+D.t[frame].toFixed(3)+' / '+t1.toFixed(3)+' s';}
 function at(t){var a=0,b=n-1;if(t>=D.t[b])return b;  // the last sample with t_k <= t
  while(b-a>1){var m=(a+b)>>1;if(D.t[m]<=t)a=m;else b=m;}return a;}
 function tick(){
  if(playing){var now=performance.now()/1000;
   if(start===null)start=now-(D.t[frame]-t0);
   var t=t0+(now-start);
   if(t>t1){if(lp.checked&&n>1){start=now;t=t0;}else{t=t1;playing=false;
    play.textContent='play';}}
   frame=at(t);draw();}
  setTimeout(tick,33);}
 play.onclick=function(){playing=!playing;start=null;
  if(playing&&frame==n-1)frame=0;play.textContent=playing?'pause':'play';};
 sl.oninput=function(){frame=+sl.value;start=null;draw();};
 if(dim==3){
  cv.onpointerdown=function(e){drag=[e.clientX,e.clientY,yaw,pitch];
   cv.setPointerCapture(e.pointerId);};
  cv.onpointermove=function(e){if(!drag)return;yaw=drag[2]+0.01*(e.clientX-drag[0]);
   pitch=Math.max(-1.55,Math.min(1.55,drag[3]+0.01*(e.clientY-drag[1])));draw();};
  cv.onpointerup=function(){drag=null;};}
 draw();tick();}
document.querySelectorAll('figure.mbdk-anim').forEach(setup);
})();
"""
