# SPDX-License-Identifier: Apache-2.0
"""Hostile input files at every reader of h4pin.mechanism and the CLI options that name one
(issue 48): a FIFO, a device, a folder, a file too large, a missing one, a symbolic link to a
FIFO, foreign stores, odd encodings and paths. Each is refused in one line naming the path and
what it is (:class:`h4pin.errors.InputFileError`, exit 2 on the CLI) before anything opens it,
or read as any other file.

A FIFO blocks its reader until a writer comes, and ``/dev/zero`` never ends: every case that
could hang runs in a child process with a timeout (the API cases in one child that says which
case it starts and how each ended; a CLI case in its own), so that a regression fails here
instead of hanging the suite."""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import run_cli_in_process

from h4pin.errors import InputFileError, MalformedURDFError, ParameterError
from h4pin.mechanism import Mechanism, store

ROOT = Path(__file__).resolve().parent.parent
FIVE = ROOT / "tests" / "robots" / "5bar_linkage_iso3d"
LOOP = ROOT / "tests" / "robots" / "synthetic" / "loop.xml"
#: Seconds the child of the API cases, or a CLI case, may take before it counts as hung.
TIMEOUT = 120
#: The child's address space: an unbounded read ends here (MemoryError) rather than in the machine's.
MEMORY = 4 << 30


def _mjcf(tmp: Path, name: str, head: str) -> Path:
    """loop.xml with ``head`` inserted before its ``<worldbody>``."""
    path = tmp / name
    path.write_text(LOOP.read_text().replace("<worldbody>", f"{head}\n  <worldbody>", 1))
    return path


@pytest.fixture(scope="module")
def hostile(tmp_path_factory) -> Path:
    """A folder of hostile files: FIFOs, a folder, sparse files over the size limit, a link to a
    FIFO, MJCF files naming FIFOs and devices, foreign stores."""
    tmp = tmp_path_factory.mktemp("hostile")
    for name in ("fifo", "fifo.yaml", "fifo.xml", "fifo.nc", "mesh.stl", "tex.png", "inc.xml"):
        os.mkfifo(tmp / name)
    (tmp / "folder").mkdir()
    (tmp / "folder.zarr").mkdir()
    (tmp / "empty.zarr").mkdir()
    (tmp / "empty.zarr" / "x").write_text("not zarr")
    os.symlink(tmp / "fifo", tmp / "link.urdf")
    for name, size in (("big.urdf", 65 << 20), ("big.yaml", 65 << 20), ("big.xml", 65 << 20), ("big.stl", 1025 << 20)):
        with open(tmp / name, "wb") as f:  # sparse: no disk used
            f.truncate(size)
    (tmp / "meshes").mkdir()
    os.mkfifo(tmp / "meshes" / "part.stl")
    _mjcf(tmp, "mesh_abs.xml", f'<asset><mesh name="m" file="{tmp}/mesh.stl"/></asset>')
    _mjcf(tmp, "mesh_dir.xml", '<compiler meshdir="meshes"/><asset><mesh name="m" file="part.stl"/></asset>')
    _mjcf(tmp, "tex_dir.xml", '<compiler assetdir="."/><asset><texture name="t" type="2d" file="tex.png"/></asset>')
    _mjcf(tmp, "include.xml", '<include file="inc.xml"/>')
    _mjcf(tmp, "hfield.xml", '<asset><hfield name="h" file="/dev/zero"/></asset>')
    _mjcf(tmp, "big_mesh.xml", f'<asset><mesh name="m" file="{tmp}/big.stl"/></asset>')
    (tmp / "text.nc").write_text("not a store\n")
    (tmp / "text.zarr").write_text("not a store\n")
    zarr = pytest.importorskip("zarr")
    xr = pytest.importorskip("xarray")
    zarr.open_group(str(tmp / "foreign.zarr"), mode="w").attrs["x"] = 1
    xr.Dataset({"a": ("x", np.arange(3.0))}).to_netcdf(tmp / "foreign.nc", engine="h5netcdf")
    return tmp


#: name -> (the call, words its message must hold besides the path); ``T`` the hostile folder,
#: ``FIVE`` the five-bar's folder, ``LOOP`` the synthetic MJCF.
API = {
    "urdf FIFO": ("Mechanism.from_urdf(T / 'fifo', FIVE / 'robot.yaml')", "fifo", "FIFO"),
    "sidecar FIFO": ("Mechanism.from_urdf(FIVE / 'robot.urdf', T / 'fifo.yaml')", "fifo.yaml", "FIFO"),
    "urdf link to a FIFO": ("Mechanism.from_urdf(T / 'link.urdf', FIVE / 'robot.yaml')", "link.urdf", "FIFO"),
    "urdf /dev/zero": ("Mechanism.from_urdf('/dev/zero', FIVE / 'robot.yaml')", "/dev/zero", "device"),
    "sidecar /dev/zero": ("Mechanism.from_urdf(FIVE / 'robot.urdf', '/dev/zero')", "/dev/zero", "device"),
    "urdf folder": ("Mechanism.from_urdf(T / 'folder', FIVE / 'robot.yaml')", "folder", "a folder"),
    "sidecar folder": ("Mechanism.from_urdf(FIVE / 'robot.urdf', T / 'folder')", "folder", "a folder"),
    "urdf too large": ("Mechanism.from_urdf(T / 'big.urdf', FIVE / 'robot.yaml')", "big.urdf", "MiB"),
    "sidecar too large": ("Mechanism.from_urdf(FIVE / 'robot.urdf', T / 'big.yaml')", "big.yaml", "MiB"),
    "urdf missing": ("Mechanism.from_urdf(T / 'nothing.urdf', FIVE / 'robot.yaml')", "nothing.urdf", "no such file"),
    "sidecar missing": ("Mechanism.from_urdf(FIVE / 'robot.urdf', T / 'nothing.yaml')", "nothing.yaml",
                        "no such file"),
    "mjcf FIFO": ("Mechanism.from_mjcf(T / 'fifo.xml')", "fifo.xml", "FIFO"),
    "mjcf /dev/zero": ("Mechanism.from_mjcf('/dev/zero')", "/dev/zero", "device"),
    "mjcf folder": ("Mechanism.from_mjcf(T / 'folder')", "folder", "a folder"),
    "mjcf too large": ("Mechanism.from_mjcf(T / 'big.xml')", "big.xml", "MiB"),
    "mjcf mesh FIFO": ("Mechanism.from_mjcf(T / 'mesh_abs.xml')", "mesh.stl", "<mesh file> "),
    "mjcf meshdir FIFO": ("Mechanism.from_mjcf(T / 'mesh_dir.xml')", "part.stl", "FIFO"),
    "mjcf assetdir texture FIFO": ("Mechanism.from_mjcf(T / 'tex_dir.xml')", "tex.png", "<texture file> "),
    "mjcf include FIFO": ("Mechanism.from_mjcf(T / 'include.xml')", "inc.xml", "<include file> "),
    "mjcf hfield /dev/zero": ("Mechanism.from_mjcf(T / 'hfield.xml')", "/dev/zero", "device"),
    "mjcf mesh too large": ("Mechanism.from_mjcf(T / 'big_mesh.xml')", "big.stl", "MiB"),
    "store FIFO": ("store.open_store(T / 'fifo.nc')", "fifo.nc", "FIFO"),
    "store /dev/zero": ("store.open_store('/dev/zero')", "/dev/zero", "device"),
    "store text .nc": ("store.open_store(T / 'text.nc')", "text.nc", "cannot read it as an atlas"),
    "store foreign .nc": ("store.open_store(T / 'foreign.nc')", "foreign.nc", "did not write"),
    "store foreign .zarr": ("store.open_store(T / 'foreign.zarr')", "foreign.zarr", "did not write"),
    "store text .zarr": ("store.open_store(T / 'text.zarr')", "text.zarr", "not a folder"),
    "store folder .zarr": ("store.open_store(T / 'empty.zarr')", "empty.zarr", "not a zarr store"),
    "store missing": ("store.open_store(T / 'nothing.nc')", "nothing.nc", "no such file"),
}

CHILD = """
import json, resource, sys, traceback
from pathlib import Path
resource.setrlimit(resource.RLIMIT_AS, ({memory}, {memory}))
from h4pin.errors import H4Error
from h4pin.mechanism import Mechanism, store
T, FIVE = Path(sys.argv[1]), Path(sys.argv[2])
for name, code in json.loads(sys.argv[3]).items():
    print("START " + json.dumps(name), flush=True)
    try:
        eval(code)
        got = ["returned", ""]
    except H4Error as exc:
        got = [type(exc).__name__, str(exc)]
    except BaseException as exc:
        got = ["untyped " + type(exc).__name__, str(exc)[:300]]
    print("END " + json.dumps([name, *got]), flush=True)
"""


@pytest.fixture(scope="module")
def api_outcomes(hostile) -> dict[str, list[str]]:
    """Each API case's outcome: ``[error class, message]``, or ``["hung", ...]`` for the case the
    child was in when its time ran out."""
    code = CHILD.format(memory=MEMORY)
    cases = json.dumps({name: call for name, (call, *_) in API.items()})
    proc = subprocess.Popen([sys.executable, "-c", code, str(hostile), str(FIVE), cases], cwd=hostile,
                            env=dict(os.environ, PYTHONPATH=str(ROOT), H4PIN_WARMUP="off"), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        out, err = proc.communicate()
    outcomes, started = {}, None
    for line in out.splitlines():
        if line.startswith("START "):
            started = json.loads(line[6:])
        elif line.startswith("END "):
            name, *got = json.loads(line[4:])
            outcomes[name] = got
    if started is not None and started not in outcomes:
        outcomes[started] = ["hung", f"no answer in {TIMEOUT} s; stderr: {err[-500:]}"]
    return outcomes


@pytest.mark.parametrize("case", sorted(API))
def test_a_file_that_is_no_regular_file_is_refused_before_it_is_opened(api_outcomes, hostile, case):
    """Each reader refuses the file in one line, an InputFileError naming the path and what it
    is, in a child process that must answer within the timeout."""
    _, path, word = API[case]
    assert case in api_outcomes, f"never reached (a case before it hung?): {api_outcomes}"
    kind, message = api_outcomes[case]
    assert kind == "InputFileError", (kind, message)
    assert path in message and word in message and "\n" not in message, message


def _cli_in_child(argv: list[str], cwd: Path) -> tuple[int | str, str]:
    """``h4pin <argv>`` in a child process: its exit status (``"hung"`` past the timeout) and stderr."""
    proc = subprocess.Popen([sys.executable, "-m", "h4pin.cli", *argv], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True, start_new_session=True,
                            env=dict(os.environ, PYTHONPATH=str(ROOT), H4PIN_WARMUP="off"),
                            preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY)))
    try:
        _, err = proc.communicate(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        proc.communicate()
        return "hung", ""
    return proc.returncode, err


CLI = [
    (["atlas", "--robot", "{F}/robot.urdf", "--sidecar", "{T}/fifo.yaml", "--output", "closedloop3D_1B", "--out",
      "{T}/a.nc", "--quiet"], "fifo.yaml"),
    (["export", "--robot", "{F}/robot.urdf", "--sidecar", "{T}/fifo.yaml", "--elastic", "--out", "{T}/e.xml"],
     "fifo.yaml"),
    (["view", "--robot", "{F}/robot.urdf", "--atlas", "{T}/fifo.nc", "--out", "{T}/v.html"], "fifo.nc"),
    (["export", "--robot", "{T}/fifo.xml", "--elastic", "--out", "{T}/e.xml"], "fifo.xml"),
    (["atlas", "--robot", "{T}/mesh_dir.xml", "--output", "tip", "--out", "{T}/a.nc", "--quiet"], "part.stl"),
    (["export", "--robot", "/dev/zero", "--sidecar", "{F}/robot.yaml", "--elastic", "--out", "{T}/e.xml"],
     "/dev/zero"),
]


@pytest.mark.parametrize(("argv", "path"), CLI, ids=[f"{a[0]}-{p}" for a, p in CLI])
def test_the_cli_refuses_a_fifo_in_one_line(hostile, argv, path):
    """``h4pin atlas/export/view`` with a FIFO or a device where a file is read: exit 2 and one
    line naming it, in a child process that must answer within the timeout; nothing written."""
    before = sorted(p.name for p in hostile.iterdir())
    code, err = _cli_in_child([a.replace("{T}", str(hostile)).replace("{F}", str(FIVE)) for a in argv], hostile)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: "), (code, err)
    assert path in lines[0] and ("FIFO" in lines[0] or "device" in lines[0]), lines[0]
    assert sorted(p.name for p in hostile.iterdir()) == before


@pytest.mark.parametrize("name", ["foreign.zarr", "text.nc", "foreign.nc", "text.zarr", "empty.zarr", "nothing.nc"])
def test_view_refuses_an_atlas_h4pin_did_not_write_in_one_line(hostile, tmp_path, monkeypatch, capsys, name):
    """``h4pin view --atlas`` over a foreign zarr group, a text file, a foreign NetCDF: one line
    naming the file (these regular files and folders cannot block: run in this process)."""
    code, _, err = run_cli_in_process(["view", "--robot", str(FIVE / "robot.urdf"), "--atlas", str(hostile / name),
                                       "--out", str(tmp_path / "v.html")], monkeypatch, capsys)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: --atlas ") and name in lines[0], err
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------ files that are read as any other
def _same(a: Mechanism, b: Mechanism) -> None:
    assert (a.model.nq, a.model.nv, list(a.model.names), list(a.actuated)) == \
        (b.model.nq, b.model.nv, list(b.model.names), list(b.actuated))
    for pa, pb in zip(a.model.jointPlacements, b.model.jointPlacements, strict=True):
        np.testing.assert_array_equal(pa.homogeneous, pb.homogeneous)


@pytest.fixture(scope="module")
def five() -> Mechanism:
    return Mechanism.from_urdf(FIVE / "robot.urdf")


def test_a_robot_at_a_path_that_is_not_utf8_is_read(tmp_path, five):
    folder = tmp_path / os.fsdecode(b"caf\xe9 \xff")
    folder.mkdir()
    shutil.copy(FIVE / "robot.urdf", folder / "robot.urdf")
    shutil.copy(FIVE / "robot.yaml", folder / "robot.yaml")
    _same(Mechanism.from_urdf(folder / "robot.urdf"), five)
    _same(Mechanism.from_urdf(str(folder / "robot.urdf"), str(folder / "robot.yaml")), five)


@pytest.mark.parametrize("encoding", ["ISO-8859-1", "latin-1", "UTF-16", "utf-8", "cp1252"])
def test_a_urdf_is_read_in_the_encoding_its_declaration_states(tmp_path, five, encoding):
    """A URDF with a non-ASCII name, encoded as its XML declaration says, is the same robot."""
    text = (FIVE / "robot.urdf").read_text().replace('<robot name="onshape"', '<robot name="onshap\u00e9"', 1)
    path = tmp_path / "robot.urdf"
    path.write_bytes(f'<?xml version="1.0" encoding="{encoding}"?>\n{text}'.encode(encoding))
    shutil.copy(FIVE / "robot.yaml", tmp_path / "robot.yaml")
    mech = Mechanism.from_urdf(path)
    assert mech.name == "onshap\u00e9"
    _same(mech, five)


@pytest.mark.parametrize(("data", "word"), [
    ("<robot name='\xe9'/>".encode("latin-1"), "not UTF-8 text"),
    (b'<?xml version="1.0" encoding="klingon"?><robot name="a"/>', "'klingon', which Python does not know"),
    (b'<?xml version="1.0" encoding="ascii"?><robot name="\xe9"/>', "not ascii text"),
    (b"\x00\x01binary", "a binary file"),
    (b"<robot name='a'><link name='a'>", "not well-formed XML"),
])
def test_a_urdf_that_is_not_text_in_its_encoding_is_one_typed_line(tmp_path, data, word):
    path = tmp_path / "robot.urdf"
    path.write_bytes(data)
    shutil.copy(FIVE / "robot.yaml", tmp_path / "robot.yaml")
    with pytest.raises(MalformedURDFError, match="robot.urdf") as info:
        Mechanism.from_urdf(path)
    assert word in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("path", [None, 5, 3.5, b"robot.urdf", bytearray(b"x"), ["a"], object(), ""])
def test_a_path_of_the_wrong_type_is_a_parameter_error(path):
    calls = [lambda: Mechanism.from_urdf(path), lambda: Mechanism.from_mjcf(path), lambda: store.open_store(path)]
    if path is not None:  # sidecar=None: the URDF's path with .yaml
        calls.append(lambda: Mechanism.from_urdf(FIVE / "robot.urdf", path))
    for call in calls:
        with pytest.raises(ParameterError) as info:
            call()
        assert not isinstance(info.value, TypeError) and "\n" not in str(info.value)


def test_a_link_to_a_regular_file_is_read(tmp_path, five):
    os.symlink(FIVE / "robot.urdf", tmp_path / "robot.urdf")
    os.symlink(FIVE / "robot.yaml", tmp_path / "robot.yaml")
    _same(Mechanism.from_urdf(tmp_path / "robot.urdf"), five)


def test_a_truncated_urdf_is_one_line_on_the_cli(tmp_path, monkeypatch, capsys):
    """``export --robot <truncated URDF> --elastic``: one line (Pinocchio's C++ parser printed two
    more on the terminal), exit 2, nothing written."""
    text = (FIVE / "robot.urdf").read_text()
    (tmp_path / "trunc.urdf").write_text(text[: len(text) // 2])
    shutil.copy(FIVE / "robot.yaml", tmp_path / "trunc.yaml")
    code, _, err = run_cli_in_process(["export", "--robot", str(tmp_path / "trunc.urdf"), "--elastic", "--out",
                                       str(tmp_path / "e.xml")], monkeypatch, capsys)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and "trunc.urdf" in lines[0] and "not well-formed XML" in lines[0], err
    assert not (tmp_path / "e.xml").exists()


def test_what_pinocchio_prints_goes_into_the_message(tmp_path, capfd):
    """A well-formed URDF that Pinocchio's C++ parser refuses (a joint without a type): one
    typed error, nothing printed on the process's stderr."""
    path = tmp_path / "robot.urdf"
    path.write_text("<robot name='r'><link name='a'/><link name='b'/><joint name='j'><parent link='a'/>"
                    "<child link='b'/></joint></robot>")
    shutil.copy(FIVE / "robot.yaml", tmp_path / "robot.yaml")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(MalformedURDFError, match="Pinocchio cannot read it") as info:
            Mechanism.from_urdf(path)
    assert "\n" not in str(info.value)
    assert capfd.readouterr().err == ""


def test_a_mjcf_naming_a_missing_mesh_is_left_to_mujoco(tmp_path):
    """A mesh file that does not exist is MuJoCo's to report (a typed error naming the file)."""
    pytest.importorskip("mujoco", reason="MuJoCo reads the file: the mujoco extra")
    if not hasattr(pin, "buildModelAndLegacyConstraintsFromMJCF"):
        pytest.skip(f"needs Pinocchio >= 4 (closures read from MJCF), this is {pin.__version__}")
    path = _mjcf(tmp_path, "m.xml", '<asset><mesh name="m" file="nowhere.stl"/></asset>')
    with pytest.raises(MalformedURDFError, match="MuJoCo cannot read it.*nowhere.stl"):
        Mechanism.from_mjcf(path)


def test_the_input_checks_name_the_limit(tmp_path):
    from h4pin import files

    path = tmp_path / "x.yaml"
    path.write_bytes(b"x" * 100)
    assert files.read_input(path, "sidecar", max_bytes=100) == b"x" * 100
    with pytest.raises(InputFileError, match=r"sidecar .*x.yaml is 0.0 MiB, over the 0 MiB h4pin reads as one"):
        files.read_input(path, "sidecar", max_bytes=99)
    assert files.check_input(tmp_path, "store", folder=True) == tmp_path
    with pytest.raises(InputFileError, match="is a file, not a folder"):
        files.check_input(path, "store", folder=True)
