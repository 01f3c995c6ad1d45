# SPDX-License-Identifier: Apache-2.0
"""The meshcat viewer: numbers drawn, a real browser render, CLI errors, no process left behind."""

from __future__ import annotations

import contextlib
import html.parser
import ipaddress
import os
import shutil
import signal
import socket
import stat
import subprocess
import sys
import time
from pathlib import Path

import matplotlib.image
import numpy as np
import pinocchio as pin
import pytest
from conftest import tagged_processes

from h4pin.io import viewer
from h4pin.mechanism import scene as scene_module
from h4pin.mechanism.scene import Scene
from h4pin.stiffness.api import compliance
from h4pin.stiffness.deflection import deflected_configuration

ROOT = Path(__file__).resolve().parent.parent
needs_chromium = pytest.mark.skipif(shutil.which("chromium") is None,
                                    reason="needs Debian's chromium (apt-get install chromium)")


pytestmark = pytest.mark.usefixtures("no_process_left")


def _address(hex_address: str) -> str:
    """An address of /proc/net/tcp{,6} (host byte order, little-endian words) as text."""
    raw = bytes.fromhex(hex_address)
    words = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
    return str(ipaddress.ip_address(words))


def listening(pid: int) -> set[tuple[str, int]]:
    """(address, port) of the TCP sockets process ``pid`` listens on, from /proc (no psutil)."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        with contextlib.suppress(OSError):
            target = os.readlink(fd)
            if target.startswith("socket:["):
                inodes.add(target[len("socket:["):-1])
    out = set()
    for table in ("tcp", "tcp6"):
        for line in Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]:
            fields = line.split()
            local, state, inode = fields[1], fields[3], fields[9]
            if state == "0A" and inode in inodes:  # 0A: LISTEN
                address, port = local.split(":")
                out.add((_address(address), int(port, 16)))
    return out


def children(pid: int) -> dict[int, str]:
    """Direct children of ``pid`` (pid -> command line), from /proc/<n>/stat."""
    out = {}
    for n in filter(str.isdigit, os.listdir("/proc")):
        with contextlib.suppress(OSError):
            if int(Path(f"/proc/{n}/stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                out[int(n)] = Path(f"/proc/{n}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    return out


def alive(pid: int) -> bool:
    """The process exists and has not exited (a zombie has)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def test_listening_parses_proc_net_tcp():
    """The /proc reader against sockets this test opens itself, on known addresses."""
    with socket.socket() as a, socket.socket(socket.AF_INET6) as b:
        a.bind(("127.0.0.1", 0))
        a.listen()
        b.bind(("::1", 0))
        b.listen()
        found = listening(os.getpid())
        assert ("127.0.0.1", a.getsockname()[1]) in found and ("::1", b.getsockname()[1]) in found


def test_ellipsoid_axes_are_deflection_directions(proto, poses):
    """Along each axis a unit force deflects D parallel to it, by the radius (m/N)."""
    for x in poses[:4]:
        k = compliance(proto, x, "consistent").translational
        radii, axes = scene_module.ellipsoid_axes(k)
        assert np.linalg.det(axes) == pytest.approx(1.0)
        for r, a in zip(radii, axes.T, strict=True):
            d = k @ a
            assert np.linalg.norm(d) == pytest.approx(r, rel=1e-12)
            assert abs(d @ a) / np.linalg.norm(d) == pytest.approx(1.0, abs=1e-12)


def test_ghost_moves_d_by_the_exaggerated_deflection(proto, poses):
    x, force, factor = poses[2], np.array([3.0, -2.0, -10.0]), 500.0
    q = deflected_configuration(proto, x, force, scale=factor)
    pin.framesForwardKinematics(proto.model, proto.data, q)
    moved = proto.frame_position("D") - x[:3]
    np.testing.assert_allclose(moved, factor * compliance(proto, x, "consistent").translational @ force, rtol=1e-12)


@pytest.mark.parametrize("bad", [[0, 0, np.nan], [np.inf, 0, 0, 0, 0, 0, 0, 0], [0, 0], [[0, 0, -10]], ["a", 0, 0]])
def test_deflection_refuses_bad_loads(proto, centre, bad):
    """A NaN, infinite, wrongly sized or non-numeric load is a LoadError (an H4Error and a
    ValueError) naming the load, from deflection and deflected_configuration alike."""
    from h4pin import H4Error, LoadError
    from h4pin.stiffness.deflection import deflection

    for call in (lambda: deflection(proto, centre, bad), lambda: deflected_configuration(proto, centre, bad)):
        with pytest.raises(LoadError, match="load") as info:
            call()
        assert isinstance(info.value, H4Error) and isinstance(info.value, ValueError)


def test_scene_legend_states_the_scales(proto, centre):
    with viewer.show(proto, centre, load=[0, 0, -10], scale=2.0, exaggeration=100.0) as scene:
        text = " ".join(scene.legend)
        pid = scene.server_pid
        ports = listening(pid)
        assert {address for address, _ in ports} == {"127.0.0.1"}, ports  # this machine only, by default
        web_port = int(scene.url.split(":")[2].split("/")[0])
        assert ("127.0.0.1", web_port) in ports, (scene.url, ports)
    assert "1 um/N drawn as 2 mm" in text and "x100" in text
    assert not alive(pid) and scene.server_pid is None


def test_scene_refuses_a_bad_load_before_starting_a_server(proto, centre, no_process_left):
    from h4pin import LoadError

    for bad in ([0, 0, np.nan], [0, 0, -10, 0], "ten newtons"):
        with pytest.raises(LoadError, match="load"):
            viewer.show(proto, centre, load=bad)
    assert not tagged_processes(no_process_left)


def _render(scene: Scene, tmp: Path, name: str) -> np.ndarray:
    html = scene.write_html(tmp / f"{name}.html")
    return matplotlib.image.imread(scene_module.screenshot(html, tmp / f"{name}.png", size=(800, 600)))[..., :3]


@pytest.mark.browser
@needs_chromium
def test_browser_draws_the_robot_and_the_ellipsoid(proto, centre, tmp_path):
    """Headless Chromium renders the page: robot pixels, and the ellipsoid changes only a small,
    green region of the picture."""
    with viewer.scene(proto) as bare:
        bare.pose(centre)
        robot = _render(bare, tmp_path, "robot")
        viewer.ellipsoid(bare, centre, scale=2.0)
        bare.legend.clear()  # compare the 3-D scene only
        both = _render(bare, tmp_path, "both")
    orange = (robot[..., 0] > 0.6) & (robot[..., 1] > 0.25) & (robot[..., 1] < 0.6) & (robot[..., 2] < 0.3)
    assert orange.sum() > 500, "the forearms (orange) are not drawn"
    changed = np.abs(both - robot).sum(axis=-1) > 0.1
    assert changed.sum() > 200, f"the ellipsoid changed only {changed.sum()} pixels"
    assert changed.mean() < 0.05, "the change is not local"
    new = both[changed]
    assert np.mean((new[:, 1] > new[:, 0]) & (new[:, 1] > new[:, 2])) > 0.5, "the changed pixels are not green"
    rows, cols = np.nonzero(changed)
    assert rows.mean() > 0.5 * robot.shape[0], "the ellipsoid is not at the plate, below the actuators"


def run_cli(*args: str, umask: int | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "h4pin.cli", *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=120, preexec_fn=None if umask is None else (lambda: os.umask(umask)))


class _Links(html.parser.HTMLParser):
    """Every URL-valued attribute of a page (script and style contents are not tags)."""

    ATTRIBUTES = {"src", "href", "srcset", "data", "action", "poster", "background", "formaction"}

    def __init__(self):
        super().__init__()
        self.urls: list[str] = []
        self.inline_script_chars = 0
        self._in_script = False

    def handle_starttag(self, tag, attrs):
        self.urls += [value or "" for name, value in attrs if name in self.ATTRIBUTES]
        self._in_script = tag == "script"

    def handle_endtag(self, tag):
        self._in_script = False

    def handle_data(self, data):
        if self._in_script:
            self.inline_script_chars += len(data)


def remote_references(page: str) -> tuple[list[str], int]:
    """URL attributes of the page that would need the network, and the size of its inline scripts."""
    parser = _Links()
    parser.feed(page)
    remote = [u for u in parser.urls if u.strip().lower().startswith(("http:", "https:", "//", "ftp:", "ws:", "wss:"))]
    return remote, parser.inline_script_chars


def test_remote_reference_check_catches_a_remote_script():
    """The page check itself: a remote script or stylesheet is found, a data: URL is not."""
    page = ('<html><head><script src="http://cdn.example/three.js"></script><link href="//x.org/a.css">'
            '</head><body><img src="data:image/png;base64,AAAA"><script>var a = "http://not.a.tag";</script>'
            '</body></html>')
    remote, inline = remote_references(page)
    assert remote == ["http://cdn.example/three.js", "//x.org/a.css"] and inline == len('var a = "http://not.a.tag";')


def test_cli_writes_a_self_contained_page(tmp_path):
    out = run_cli("view", "--out", str(tmp_path / "h4.html"), "--load", "0", "0", "-10", "--field", umask=0o077)
    assert out.returncode == 0, out.stderr
    page = (tmp_path / "h4.html").read_text()
    assert "h4pin-legend" in page and "x100" in out.stdout and "field: 50 of 50 poses" in out.stdout
    remote, inline = remote_references(page)
    assert remote == [], f"the page fetches {remote}"
    assert inline > 100_000  # three.js and meshcat are inlined, not linked
    assert [p.name for p in tmp_path.iterdir()] == ["h4.html"]
    assert stat.S_IMODE((tmp_path / "h4.html").stat().st_mode) == 0o644  # even under umask 077


@needs_chromium
def test_screenshot_is_world_readable(proto, centre, tmp_path):
    with viewer.scene(proto) as scene:
        scene.pose(centre)
        page = scene.write_html(tmp_path / "h4.html")
    old = os.umask(0o077)
    try:
        png = scene_module.screenshot(page, tmp_path / "h4.png", size=(200, 150))
    finally:
        os.umask(old)
    assert stat.S_IMODE(png.stat().st_mode) == 0o644


@pytest.mark.parametrize(
    ("args", "message"),
    [(["--pose", "0", "0", "-0.9", "0"], "cannot reach"),
     (["--variant", "symmetric"], "singular"),
     (["--pose", "0", "0"], "--pose takes 4 numbers X Y Z THETA (m, rad), got 2: 0 0"),
     (["--pose", "0", "0", "-0.6", "0", "0.1"], "--pose takes 4 numbers X Y Z THETA (m, rad), got 5"),
     (["--pose", "0", "0", "nan", "0"], "--pose must be finite numbers, got 0 0 nan 0"),
     (["--load", "0", "0", "x"], "--load takes 3 numbers FX FY FZ (N), got 2: 0 0"),
     (["--load", "0", "0", "-inf"], "--load must be finite"),
     (["--scale", "0"], "--scale must be a finite number > 0 (mm per um/N), got 0"),
     (["--scale", "-2"], "--scale must be a finite number > 0 (mm per um/N), got -2"),
     (["--exaggeration", "nan"], "--exaggeration must be a finite number > 0, got nan"),
     (["--exaggeration", "inf"], "--exaggeration must be a finite number > 0, got inf"),
     (["--model", "exact"], "Invalid value for '--model': 'exact' is not one of 'paper', 'consistent'"),
     (["--mode", "0"], "--mode must be >= 1"),
     (["--mode", "99"], "mode index must be an integer in 0..15"),
     (["--mode", "1", "--payload", "-1"], "--payload must be a finite mass >= 0"),
     (["--payload", "0.5"], "--payload goes with --mode")],
)
def test_cli_bad_input_is_one_line_and_writes_nothing(tmp_path, args, message):
    target = tmp_path / "h4.html"
    out = run_cli("view", "--out", str(target), *args)
    assert out.returncode == 2
    assert message in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert "Traceback" not in out.stderr
    assert not target.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("where", ["folder", "missing folder"])
def test_cli_html_must_name_a_file_in_an_existing_folder(tmp_path, where):
    target = tmp_path if where == "folder" else tmp_path / "nope" / "h4.html"
    out = run_cli("view", "--out", str(target))
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert out.stderr.startswith(f"error: --out {target}")
    assert ("is a folder" if where == "folder" else "does not exist") in out.stderr
    assert list(tmp_path.iterdir()) == []


def _default_interrupts() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGQUIT, signal.SIG_DFL)


def start_view(*args: str) -> tuple[subprocess.Popen, int]:
    """``h4pin view`` serving a scene; returns the command and its meshcat server's pid."""
    # faulthandler: a command that does not stop is sent SIGABRT and its stacks read (see _wait).
    # SIGINT and SIGQUIT at their defaults, as a terminal starts a command: in a long session the
    # child inherited them ignored now and then (measured: SigIgn 0x1001006, as while another
    # thread sits in libc's system()), and an ignored SIGINT is the shell's choice, not a bug.
    proc = subprocess.Popen([sys.executable, "-X", "faulthandler", "-m", "h4pin.cli", "view", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                            preexec_fn=_default_interrupts)
    deadline = time.monotonic() + 60
    line = ""
    while "meshcat: http" not in line and time.monotonic() < deadline and proc.poll() is None:
        line = proc.stdout.readline()
    assert "meshcat: http" in line, proc.stderr.read() if proc.poll() is not None else "no URL printed"
    servers = [pid for pid, cmd in children(proc.pid).items() if "h4pin.mechanism.meshcat_server" in cmd]
    assert len(servers) == 1, children(proc.pid)
    return proc, servers[0]


@pytest.mark.parametrize(
    ("sig", "code", "host"),
    [(signal.SIGINT, 130, None), pytest.param(signal.SIGTERM, 143, None, marks=pytest.mark.slow),
     pytest.param(signal.SIGHUP, 129, "0.0.0.0", marks=pytest.mark.slow)],
)
def test_cli_server_stops_on_signals(sig, code, host):
    """Without --html: the URL is printed; the server listens on 127.0.0.1 unless --host says
    otherwise; SIGINT (Ctrl-C), SIGTERM and SIGHUP stop the command and its meshcat server,
    with exit status 128 + the signal's number."""
    proc, server = start_view(*([] if host is None else ["--host", host]))
    try:
        ports = listening(server)
        assert {address for address, _ in ports} == {host or "127.0.0.1", "127.0.0.1"}, ports
        assert len(ports) == 2  # the page (on --host) and meshcat's command socket (always local)
        proc.send_signal(sig)
        assert _wait(proc, 30) == code
        assert "stopped" in proc.stdout.read()
        assert not alive(server), "the meshcat server outlived the command"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _wait(proc: subprocess.Popen, timeout: float) -> int:
    """The command's exit status; if it is still running after ``timeout`` s, a failure quoting
    its signal masks and every thread's stack (faulthandler on SIGABRT)."""
    try:
        return proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        with open(f"/proc/{proc.pid}/status") as fh:
            masks = [line.strip() for line in fh if line.startswith(("SigBlk", "SigIgn", "SigCgt"))]
        proc.send_signal(signal.SIGABRT)
        _, err = proc.communicate(timeout=30)
        pytest.fail(f"h4pin view did not stop within {timeout} s of the signal; {masks}; stderr:\n{err}")


def test_server_stops_when_the_viewer_is_killed():
    """SIGKILL leaves no chance to clean up: the server notices its parent is gone and stops."""
    proc, server = start_view()
    proc.kill()
    proc.wait()
    deadline = time.monotonic() + 10
    while alive(server) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not alive(server), "the meshcat server outlived a killed viewer"


def _animation(html: str) -> dict:
    """The set_animation command of a static meshcat page (msgpack blobs, base64)."""
    import base64
    import re

    import umsgpack

    for blob in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html):
        msg = umsgpack.unpackb(base64.b64decode(blob))
        if msg["type"] == "set_animation":
            return msg
    raise AssertionError("the page has no animation")


def test_mode_animation_moves_the_plate_by_the_mode_shape(proto, centre):
    """The static page keeps the animation, and at a quarter period the central bar has moved
    rigidly by amplitude x the mode's plate motion: D by a dD, the bar turned by exp(a dOmega)."""
    import pinocchio as pin

    from h4pin.elastic import modes
    from h4pin.mechanism import Payload

    payload = Payload(0.5)
    with viewer.scene(proto) as scene:
        scene.pose(centre)
        freq, amp = viewer.animate_mode(scene, centre, 1, payload, frames=8)
        anim = _animation(scene.html())
    ref = modes(proto, centre, payload)
    assert freq == pytest.approx(ref.frequencies[1], rel=1e-12)
    tracks = {a["path"].rsplit("/", 1)[-1]: a["clip"]["tracks"] for a in anim["animations"]}
    assert len(tracks) == len(proto.visual_model.geometryObjects)

    def placement(name: str, k: int) -> pin.SE3:
        pos, quat = (next(t for t in tracks[name] if t["name"] == f".{key}")["keys"][k]["value"]
                     for key in ("position", "quaternion"))
        return pin.SE3(pin.Quaternion(quat[3], *quat[:3]).matrix(), np.array(pos))

    motion = placement("central_bar_0", 2) * placement("central_bar_0", 0).inverse()  # sin(2 pi 2/8) = 1
    tp = amp * ref.shapes_tp[1]
    d = centre[:3]  # the tracks are in the robot's frame (the scene's lift is on the root)
    assert np.linalg.norm(motion.act(d) - d - tp[:3]) < 1e-9 * max(1.0, np.linalg.norm(tp[:3]))
    assert np.linalg.norm(pin.log3(motion.rotation) - tp[3:6]) < 1e-9
    assert np.linalg.norm(tp[:3]) > 1e-3  # visible: millimetres on screen


def test_view_in_process_leaves_the_callers_signal_handlers(tmp_path, monkeypatch, capsys):
    """Run in-process (a test, a notebook), `view` restores SIGINT, SIGTERM and SIGHUP as it found
    them: a process it then spawns must still stop on Ctrl-C (its SIG_IGN used to be inherited)."""
    from h4pin import cli

    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    for argv in (["view", "--out", str(tmp_path / "v.html")], ["view", "--host", "999.1.1.1"]):
        monkeypatch.setattr(sys, "argv", ["h4pin", *argv])
        with pytest.raises(SystemExit):
            cli.main()
        capsys.readouterr()
        assert {sig: signal.getsignal(sig) for sig in before} == before, argv
