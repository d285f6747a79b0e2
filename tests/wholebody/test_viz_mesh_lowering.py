"""Meshes on a scene's page: Meshcat's current mesh form, and each distinct mesh file's bytes written once.

A small robot from a URDF written here draws one STL sphere on two links and one OBJ box on a third
(`wholebody.viz.lowering`). The browser tests (headless Chromium, skipped with one line when it is missing,
unless CARTPUSH_REQUIRE_BROWSER=1) read the page's console and check that the meshes are drawn.
"""

from __future__ import annotations

import base64
import os
import re
import struct

import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
import pytest
import umsgpack
from PIL import Image

from robots.loading import LoadedRobot
from wholebody.viz import Scene
from wholebody.viz.browser import console_messages, find_chromium, screenshot
from wholebody.viz.lowering import SHARE_MIN_BYTES, lower_command, replay_js, share_values
from wholebody.viz.scene import _RecordingWindow

DEPRECATION = "_meshfile is deprecated"
#: Where the URDF puts each link's mesh (x, y, z of the link on the planar root), and the mesh's radius.
PLACES = {"left": (0.0, 0.5, 0.4), "right": (0.0, -0.5, 0.4), "box": (0.6, 0.0, 0.3)}
RADIUS = 0.2


def sphere_stl(radius: float, n: int = 16) -> bytes:
    """A binary STL of a UV sphere (2 n (n - 1) triangles, about 25 kB for n = 16)."""
    theta, phi = np.meshgrid(np.linspace(0, np.pi, n + 1), np.linspace(0, 2 * np.pi, n + 1), indexing="ij")
    p = radius * np.stack((np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)), axis=-1)
    tris = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = p[i, j], p[i + 1, j], p[i + 1, j + 1], p[i, j + 1]
            if i > 0:
                tris.append((a, b, d))
            if i < n - 1:
                tris.append((b, c, d))
    out = [b"\0" * 80, struct.pack("<I", len(tris))]
    for tri in tris:
        normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
        normal /= np.linalg.norm(normal)
        out.append(struct.pack("<12fH", *normal, *tri[0], *tri[1], *tri[2], 0))
    return b"".join(out)


def box_obj(half: float) -> str:
    """An OBJ text of a cube of half-size `half` (12 triangles), padded with comments past `SHARE_MIN_BYTES`."""
    v = [(x, y, z) for x in (-half, half) for y in (-half, half) for z in (-half, half)]
    faces = [(1, 3, 4, 2), (5, 6, 8, 7), (1, 2, 6, 5), (3, 7, 8, 4), (1, 5, 7, 3), (2, 4, 8, 6)]
    lines = ["# cube"] * 100 + [f"v {x} {y} {z}" for x, y, z in v]
    lines += [f"f {a} {b} {c}\nf {a} {c} {d}" for a, b, c, d in faces]
    return "\n".join(lines) + "\n"


def _link(name: str, mesh: str, xyz: tuple[float, float, float]) -> str:
    return f"""<link name="{name}"><visual><geometry><mesh filename="{mesh}"/></geometry>
  <material name="m_{name}"><color rgba="0.9 0.4 0.1 1"/></material></visual></link>
<joint name="j_{name}" type="fixed"><parent link="base"/><child link="{name}"/>
  <origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}"/></joint>
"""


@pytest.fixture(scope="module")
def mesh_robot(tmp_path_factory):
    """A robot on a planar root: an STL sphere on links `left` and `right`, an OBJ cube on link `box`."""
    tmp = tmp_path_factory.mktemp("mesh_robot")
    (tmp / "sphere.stl").write_bytes(sphere_stl(RADIUS))
    (tmp / "cube.obj").write_text(box_obj(RADIUS), encoding="utf-8")
    links = [_link(k, str(tmp / ("cube.obj" if k == "box" else "sphere.stl")), xyz) for k, xyz in PLACES.items()]
    urdf = tmp / "mesh_bot.urdf"
    urdf.write_text(f'<robot name="mesh_bot"><link name="base"/>{"".join(links)}</robot>', encoding="utf-8")
    model = pin.buildModelFromUrdf(str(urdf), pin.JointModelPlanar())
    visual = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.VISUAL, package_dirs=[str(tmp)])
    collision = pin.buildGeomFromUrdf(model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[str(tmp)])
    return LoadedRobot(
        name="mesh_bot",
        urdf=urdf,
        model=model,
        data=model.createData(),
        visual_model=visual,
        collision_model=collision,
        visual_data=pin.GeometryData(visual),
        collision_data=pin.GeometryData(collision),
    )


@pytest.fixture(scope="module")
def page(mesh_robot, tmp_path_factory):
    """(scene commands, page text, page path) of the mesh robot alone."""
    path = tmp_path_factory.mktemp("mesh_page") / "mesh.html"
    with Scene([mesh_robot]) as sc:
        sc.save_html(path, controls=False)
        commands = sc.window.commands()
    return commands, path.read_text(encoding="utf-8"), path


def page_commands(html: str) -> list[bytes]:
    """The commands the page hands the viewer, decoded as its script does (`sharedValues`, `joinPieces`)."""
    table = re.search(r"const sharedValues = \[(.*?)\];", html, re.S)
    assert table is not None, "the page has no sharedValues table"
    shared = [base64.b64decode(s) for s in re.findall(r'b64\("([A-Za-z0-9+/=]*)"\)', table.group(1))]
    out = []
    for call in re.findall(r"viewer\.handle_command_bytearray\((.*?)\);\n", html):
        whole = re.fullmatch(r'b64\("([A-Za-z0-9+/=]*)"\)', call)
        if whole:
            out.append(base64.b64decode(whole.group(1)))
            continue
        parts = re.fullmatch(r"joinPieces\(\[(.*)\]\)", call)
        assert parts is not None, f"unknown call {call[:80]}"
        pieces = re.findall(r'"([A-Za-z0-9+/=]*)"|(\d+)', parts.group(1))
        out.append(b"".join(base64.b64decode(s) if s else shared[int(i)] for s, i in pieces))
    return out


def mesh_geometries(commands: list[bytes]) -> list[dict]:
    """The geometries of the scene's ``set_object`` commands that carry a mesh file (``format`` and ``data``)."""
    found = []
    for c in commands:
        data = umsgpack.unpackb(c)
        if data["type"] == "set_object":
            found += [g for g in data["object"]["geometries"] if "format" in g]
    return found


def test_meshes_are_sent_as_meshfile_geometry(page):
    commands, html, _ = page
    geometries = mesh_geometries(page_commands(html))
    assert sorted(g["format"] for g in geometries) == ["obj", "stl", "stl"]
    assert {g["type"] for g in geometries} == {"_meshfile_geometry"}
    assert b"\xa9_meshfile\xa6format" not in b"".join(commands)  # no "_meshfile" type, as msgpack writes it


def test_page_replays_exactly_the_recorded_commands(page):
    commands, html, _ = page
    assert page_commands(html) == commands


def test_a_mesh_used_twice_is_embedded_once(page):
    commands, html, _ = page
    stl = sphere_stl(RADIUS)
    script = html.split("new MeshCat.Viewer(")[1]  # the scene's commands, after the viewer's own JavaScript
    blobs = [base64.b64decode(s) for s in re.findall(r'"([A-Za-z0-9+/=]{200,})"', script)]
    holding = [b for b in blobs if stl in b]
    assert len(holding) == 1, f"the sphere's STL is in {len(holding)} base64 strings of the page"
    spheres = [g for g in mesh_geometries(page_commands(html)) if g["format"] == "stl"]
    assert len(spheres) == 2 and all(g["data"].data == stl for g in spheres)
    assert replay_js(commands) in html
    assert len(replay_js(commands)) < len(inline_calls(commands)) - 1.2 * len(stl)


def inline_calls(commands: list[bytes]) -> str:
    """The page's calls as they were before sharing: every command whole, in base64."""
    return "".join(f'viewer.handle_command_bytearray(b64("{base64.b64encode(c).decode()}"));\n' for c in commands)


def test_share_values_joins_back_and_shares_only_large_repeated_values():
    big, once, small = b"x" * 5000, "y" * 3000, "z" * 10
    commands = [
        umsgpack.packb(
            {"type": "set_object", "object": {"geometries": [{"data": big}, {"data": small}, {"data": big}]}}
        ),
        umsgpack.packb({"type": "set_object", "object": {"geometries": [{"data": once}, {"data": small}]}}),
        umsgpack.packb(
            {"type": "set_object", "object": {"geometries": [{"data": umsgpack.Ext(0x12, big)}, {"d": big}]}}
        ),
        umsgpack.packb({"type": "set_transform", "matrix": [1.0] * 16}),
    ]
    shared = share_values(commands)
    assert [shared.joined(i) for i in range(len(commands))] == commands
    assert shared.values == [umsgpack.packb(big)] and len(shared.values[0]) >= SHARE_MIN_BYTES
    assert [p for p in shared.commands[0] if isinstance(p, int)] == [0, 0]
    assert [p for p in shared.commands[2] if isinstance(p, int)] == [0]  # the Ext (written once) stays in place
    assert shared.commands[1] == [commands[1]] and shared.commands[3] == [commands[3]]
    js = replay_js(commands)
    assert js.count("handle_command_bytearray(joinPieces(") == 2 and js.count('handle_command_bytearray(b64("') == 2


def test_live_viewer_gets_the_lowered_form(tmp_path):
    class Live:
        def __init__(self) -> None:
            self.sent: list[dict] = []

        def send(self, command) -> None:
            self.sent.append(command.lower())

    (tmp_path / "sphere.stl").write_bytes(sphere_stl(RADIUS))
    live = Live()
    window = _RecordingWindow(live)
    meshcat.Visualizer(window=window)["m"].set_object(
        mg.StlMeshGeometry.from_file(str(tmp_path / "sphere.stl")), mg.MeshPhongMaterial()
    )
    recorded = umsgpack.unpackb(window.commands()[0])["object"]["geometries"][0]
    assert [d["object"]["geometries"][0]["type"] for d in live.sent] == ["_meshfile_geometry"]
    assert recorded["type"] == "_meshfile_geometry" and recorded["data"].data == sphere_stl(RADIUS)


def test_lower_command_leaves_other_commands_alone():
    obj = {"type": "set_object", "path": "/a", "object": {"geometries": [{"type": "BoxGeometry"}], "object": {}}}
    assert lower_command({"type": "set_transform", "matrix": [1.0]}) == {"type": "set_transform", "matrix": [1.0]}
    assert lower_command(dict(obj)) == obj


# -- in the browser --------------------------------------------------------------------------------------------
CHROMIUM = find_chromium()
needs_browser = pytest.mark.skipif(
    CHROMIUM is None and os.environ.get("CARTPUSH_REQUIRE_BROWSER") != "1",
    reason="browser tests need headless Chromium: apt-get install chromium",
)
WIDTH, HEIGHT = 800, 600


def _render(html, png, profile) -> tuple[np.ndarray, list[str]]:
    if CHROMIUM is None:
        raise RuntimeError("browser tests need headless Chromium [CARTPUSH_REQUIRE_BROWSER=1]")
    proc = screenshot(CHROMIUM, html, png, size=(WIDTH, HEIGHT), profile=profile, budget_ms=3000, console=True)
    return np.asarray(Image.open(png).convert("RGB"), dtype=float), console_messages(proc.stderr)


@needs_browser
def test_browser_draws_the_meshes_without_deprecation_warnings(mesh_robot, tmp_path):
    pages = {}
    with Scene([mesh_robot]) as sc:
        for name in ("shown", "hidden"):
            if name == "hidden":
                sc.viewer["mesh_bot"].set_property("visible", False)
            sc.save_html(tmp_path / f"{name}.html", controls=False)
            pages[name] = _render(tmp_path / f"{name}.html", tmp_path / f"{name}.png", tmp_path / "profile")
        uv = sc.camera.project(np.array(list(PLACES.values())), WIDTH, HEIGHT)
    (shown, messages), (hidden, _) = pages["shown"], pages["hidden"]
    assert not [m for m in messages if DEPRECATION in m or "Unsupported mesh" in m], messages
    for name, (u, v) in zip(PLACES, np.round(uv).astype(int)):
        assert 20 <= u < WIDTH - 20 and 20 <= v < HEIGHT - 20, f"{name} is off the page at {(u, v)}"
        diff = np.abs(shown[v - 4 : v + 5, u - 4 : u + 5] - hidden[v - 4 : v + 5, u - 4 : u + 5]).mean()
        assert diff > 40, f"the {name} mesh is not drawn: mean difference {diff:.1f} at {(u, v)}"
