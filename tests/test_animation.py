"""The animation of a scene run (issue 39, item 6): its frames are the run's own samples at their
own times, the first and last always among them; a drawn point is the body's centre plus its
rotation times the body point, checked against rotations computed here from the samples
(cos/sin of a planar angle; the quaternion's matrix written out); bad input is refused by name;
and the page plays in headless Chromium (its canvas' data-frame and data-t advance, and it
draws)."""
import json
import re
import subprocess
import sys

import numpy as np
import pytest

import mbdk
from mbdk.animation import animation_html, frame_indices, frames, write_animation
from test_report_browser import BROWSER, FLAGS, needs_browser


def _index(d, owner, point):
    """The drawn point of owner at the body point (the first such)."""
    p = np.pad(np.asarray(point, float), (0, 3 - len(point)))
    return next(k for k, (o, q) in enumerate(d.points) if o == owner and np.allclose(q, p))


def test_decimation_keeps_the_first_and_last_sample_and_spreads_the_rest():
    k = frame_indices(1001, 240)
    assert k[0] == 0 and k[-1] == 1000 and len(k) <= 240
    assert np.all(np.diff(k) > 0) and np.diff(k).max() - np.diff(k).min() <= 1
    assert np.array_equal(frame_indices(7, 240), np.arange(7))


def test_a_pendulums_joint_point_is_its_centre_plus_its_rotated_body_point():
    sc = mbdk.scene("physical_pendulum")
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=2.0)       # 2001 samples
    t, xyz, d = frames(r, sc, max_frames=100)
    shown = frame_indices(len(r.t), 100)
    assert np.array_equal(t, r.t[shown]) and t[0] == 0.0 and t[-1] == r.t[-1]
    j = sc.joints[0]
    k = _index(d, j.body1, j.point1)
    x, y, phi = r.q[shown, 0], r.q[shown, 1], r.q[shown, 2]
    px, py = j.point1
    tip = np.column_stack([x + np.cos(phi) * px - np.sin(phi) * py,
                           y + np.sin(phi) * px + np.cos(phi) * py])
    assert np.abs(xyz[:, k, :2] - tip).max() < 1e-14
    # and it is where the joint holds it, the ground point (to the run's position residual):
    # a point drawn off the body, or a frame from another sample, would be metres off
    anchor = _index(d, "ground", j.point2)
    assert np.abs(xyz[:, k] - xyz[:, anchor]).max() < 1e-6
    # the body swings (its centre moves): the frames are not one pose repeated
    assert np.ptp(xyz[:, _index(d, j.body1, (0.0, 0.0)), 0]) > 0.1


def test_a_heavy_tops_drawn_point_is_the_quaternions_rotation_of_its_body_point():
    sc = mbdk.scene("heavy_top")
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0, formulation="projection")
    t, xyz, d = frames(r, sc, max_frames=50)
    shown = frame_indices(len(r.t), 50)
    j = sc.joints[0]
    k = _index(d, j.body1, j.point1)
    for f, s in enumerate(shown):
        p0, p1, p2, p3 = r.q[s, 3:7] / np.linalg.norm(r.q[s, 3:7])
        # the Euler-parameter rotation matrix (Fekete 2023, (5.40); Shabana's form)
        rot = 2 * np.array([[p0**2 + p1**2 - 0.5, p1*p2 - p0*p3, p1*p3 + p0*p2],
                            [p1*p2 + p0*p3, p0**2 + p2**2 - 0.5, p2*p3 - p0*p1],
                            [p1*p3 - p0*p2, p2*p3 + p0*p1, p0**2 + p3**2 - 0.5]])
        assert np.abs(xyz[f, k] - (r.q[s, :3] + rot @ j.point1)).max() < 1e-14
    # the top's tip stays on the pivot it is joined to (the ground point at the origin), while
    # its centre moves
    assert np.abs(xyz[:, k]).max() < 1e-6
    centre = _index(d, "top", (0.0, 0.0, 0.0))
    assert np.ptp(xyz[:, centre, 0]) > 1e-3


def test_the_fragment_carries_the_frames_as_json_and_the_page_is_self_contained(tmp_path):
    sc = mbdk.scene("double_pendulum")
    r = mbdk.simulate(sc, "dopri54", t_end=1.0, dt_out=0.01)
    frag = animation_html(r, sc, max_frames=50)
    data = json.loads(re.search(r"class='mbdk-anim-data'>(.*?)</script>", frag, re.S).group(1))
    t, xyz, _d = frames(r, sc, max_frames=50)
    assert data["t"] == pytest.approx(t.tolist(), rel=1e-6)
    assert np.abs(np.array(data["xyz"]) - xyz[:, :, :2].reshape(len(t), -1)).max() < 1e-5
    # late times keep every digit: a run from t0 = 1000 s shows each of its frames at its own
    # time (rounded, many would share one and never play)
    late = mbdk.simulate(sc, "rk4", h=1e-3, t0=1000.0, t_end=1000.5)
    frag = animation_html(late, sc, title="</script><!--")
    data = json.loads(re.search(r"class='mbdk-anim-data'>(.*?)</script>", frag, re.S).group(1))
    t_late, _xyz, _d = frames(late, sc)
    assert data["t"] == t_late.tolist() and len(set(data["t"])) == len(t_late)
    assert data["title"] == "</script><!--"          # escaped in the page, itself in the data
    page = write_animation(r, sc, tmp_path / "dp.html").read_text()
    # nothing loaded from elsewhere: no script or style sheet by address
    assert "<script>" in page and not re.search(r"<(script|link)[^>]+(src|href)=", page)


def test_bad_input_is_named(tmp_path):
    sc = mbdk.scene("double_pendulum")
    r = mbdk.simulate(sc, "rk4", h=1e-2, t_end=0.1)
    with pytest.raises(mbdk.InvalidInputError, match="max_frames: 1"):
        animation_html(r, sc, max_frames=1)
    with pytest.raises(mbdk.InvalidInputError, match="scene: 'four_bar'.*not the scene"):
        animation_html(r, mbdk.scene("four_bar"))
    with pytest.raises(mbdk.InvalidInputError, match="result: ODEResult"):
        animation_html(mbdk.solve_ode("pendulum", "rk4", h=0.1, t_end=1.0), sc)
    with pytest.raises(mbdk.InvalidInputError, match=r"dp\.png: an animation is an HTML page"):
        write_animation(r, sc, tmp_path / "dp.png")
    assert not (tmp_path / "dp.png").exists()


def test_mbdk_animate_writes_a_page_and_refuses_a_bad_frame_count(tmp_path):
    out = tmp_path / "fb.html"
    ok = subprocess.run([sys.executable, "-m", "mbdk", "animate", "four_bar", "--method",
                         "dopri54", "--t-end", "2", "--out", out], capture_output=True,
                        text=True)
    assert ok.returncode == 0, ok.stderr
    # an error-controlled run is sampled for the frames (240 of them), not only at its ends
    data = json.loads(re.search(r"class='mbdk-anim-data'>(.*?)</script>", out.read_text(),
                                re.S).group(1))
    assert len(data["t"]) >= 200 and data["t"][-1] == 2.0
    bad = subprocess.run([sys.executable, "-m", "mbdk", "animate", "four_bar", "--method",
                          "rk4", "--h", "1e-3", "--t-end", "1", "--frames", "1", "--out",
                          tmp_path / "x.html"], capture_output=True, text=True)
    assert bad.returncode == 2 and "--frames 1" in bad.stderr and "no file written" in bad.stderr


def _canvases(dom: str) -> list[tuple[int, float]]:
    return [(int(f), float(t)) for f, t in
            re.findall(r"<canvas[^>]*data-frame=\"(\d+)\" data-t=\"([-\d.e]+)\"", dom)]


@needs_browser
@pytest.mark.parametrize("name", ["double_pendulum", "heavy_top"])
def test_the_animation_plays_and_draws_in_headless_chromium(name, tmp_path):
    """5 s of motion played for 2 s of the browser's virtual time: the frame shown has moved
    on to t near 2 s (a frozen or looping player would show 0), and the canvas holds lines."""
    sc = mbdk.scene(name)
    r = mbdk.simulate(sc, "dopri54", t_end=5.0, dt_out=0.02)
    page = write_animation(r, sc, tmp_path / f"{name}.html")
    dom = subprocess.run([BROWSER, *FLAGS, "--virtual-time-budget=2000", "--dump-dom",
                          page.as_uri()], check=True, capture_output=True, text=True,
                         timeout=120).stdout
    (frame, t), = _canvases(dom)
    assert frame > 0 and 1.0 < t < 3.0
    assert "t = " in dom and "/ 5.000 s" in dom
    png = tmp_path / f"{name}.png"
    subprocess.run([BROWSER, *FLAGS, f"--screenshot={png}", "--window-size=600,450",
                    "--virtual-time-budget=500", page.as_uri()], check=True,
                   capture_output=True, timeout=120)
    import matplotlib.image
    pixels = matplotlib.image.imread(png)[..., :3]
    # the canvas sits below the heading at the page's left: within it, drawn pixels (bodies,
    # joints) other than its one-pixel grey border
    inner = pixels[100:380, 20:400]
    assert np.mean(np.any(inner < 0.6, axis=-1)) > 0.002


@needs_browser
def test_the_reports_scene_motion_page_plays_every_built_in_scene(tmp_path, root):
    """The report's animations page: one animation per built-in scene, each advanced after 2 s
    of virtual time (a run of 3 s: t near 2), and the front page links it and names the hard
    case it met (the redundant parallelogram)."""
    out = tmp_path / "report"
    subprocess.run([sys.executable, "-m", "mbdk", "report", "--quick", "--out", out,
                    "--studies", root / "studies", "--only", "scene_motion"], check=True,
                   capture_output=True)
    dom = subprocess.run([BROWSER, *FLAGS, "--virtual-time-budget=2000", "--dump-dom",
                          (out / "scene_motion.html").as_uri()], check=True,
                         capture_output=True, text=True, timeout=120).stdout
    shown = _canvases(dom)
    assert len(shown) == len(mbdk.scenes("all")) == 15
    assert all(f > 0 and 1.0 < t < 3.0 for f, t in shown), shown
    front = (out / "index.html").read_text()
    assert "href='scene_motion.html'>redundant joints</a>" in front
    assert "RedundantConstraintsError" in front
