"""How a scene's meshes reach the page: Meshcat's current mesh form, and each distinct mesh file's bytes once.

Pinocchio's `MeshcatVisualizer` loads an STL or OBJ visual as meshcat-python's ``MeshGeometry``, whose
``lower()`` still writes the geometry type ``"_meshfile"``; the viewer's JavaScript then logs
``_meshfile is deprecated. Please use _meshfile_geometry ...`` once per mesh (70 times for TIAGo++) and
handles it as ``"_meshfile_geometry"``. `lower_command` writes that type directly: the same geometry,
parsed by the same loader, without the warning.

Each geometry node is a ``set_object`` command of its own carrying the whole mesh file, so a mesh drawn by
several links (TIAGo's left and right arms, its 18 finger links) was embedded once per link: 70 STL files,
7.9 MB of mesh bytes, where 21 distinct files make 4.7 MB. `share_values` cuts the commands at the large
values (mesh files, textures, vertex arrays: `SHARE_MIN_BYTES` and more) that two or more of them carry and
keeps each such value once; `replay_js` writes the page's script that glues the pieces back into the very
bytes of each command. The viewer receives exactly the commands it received before; the page carries each
mesh once.
"""

from __future__ import annotations

import base64
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import umsgpack

#: The geometry type meshcat-python 0.3 writes for a mesh file, deprecated by its viewer.
DEPRECATED_MESHFILE = "_meshfile"
#: What the viewer wants instead: a mesh file as a geometry (with the material of the object holding it).
MESHFILE_GEOMETRY = "_meshfile_geometry"
#: Values of a command whose msgpack encoding is at least this long are stored once per page.
SHARE_MIN_BYTES = 1024


def lower_command(data: dict[str, Any]) -> dict[str, Any]:
    """Return the lowered Meshcat command `data` with each ``"_meshfile"`` geometry typed ``"_meshfile_geometry"``.

    Changes `data` in place (a command's ``lower()`` builds a fresh dict each call). Other commands, and
    objects of type ``"_meshfile_object"`` (Pinocchio's Collada meshes), are returned as they are.
    """
    if data.get("type") == "set_object":
        for geometry in data.get("object", {}).get("geometries", ()):
            if geometry.get("type") == DEPRECATED_MESHFILE:
                geometry["type"] = MESHFILE_GEOMETRY
    return data


class Lowered:
    """A command lowered already: what a live Meshcat window's ``send`` calls ``lower()`` on."""

    def __init__(self, data: dict[str, Any]) -> None:
        self.data = data

    def lower(self) -> dict[str, Any]:
        """Return the lowered command."""
        return self.data


@dataclass(frozen=True)
class SharedCommands:
    """Commands cut at their large values: `values` holds each distinct value's msgpack bytes once.

    ``commands[i]`` is a list of pieces, each either bytes of the command or an int, the index in
    `values` of the bytes that go there; `joined` puts a command back together.
    """

    values: list[bytes]
    commands: list[list[bytes | int]]

    def joined(self, i: int) -> bytes:
        """Return command `i` as bytes (its pieces, with the shared values in place)."""
        return b"".join(self.values[p] if isinstance(p, int) else p for p in self.commands[i])


def _large_values(obj: Any, min_bytes: int) -> Iterator[bytes]:
    """Yield the msgpack bytes of each string, byte string or extension value of `obj` at least `min_bytes` long.

    In the order msgpack writes them (a dict's items in order, a list's elements in order).
    """
    if isinstance(obj, dict):
        for key, value in obj.items():
            yield from _large_values(key, min_bytes)
            yield from _large_values(value, min_bytes)
    elif isinstance(obj, (list, tuple)):
        for item in obj:
            yield from _large_values(item, min_bytes)
    elif isinstance(obj, (str, bytes, umsgpack.Ext)):
        packed = umsgpack.packb(obj)
        if len(packed) >= min_bytes:
            yield packed


def _cut(command: bytes, values: list[bytes], index: dict[bytes, int]) -> list[bytes | int]:
    """Return the pieces of `command` (msgpack bytes) with its `values` (their msgpack bytes, in the order they
    are written) replaced by their index (added to `index`).

    The pieces are slices of `command`, so they join back into its bytes whatever they hold.
    """
    pieces: list[bytes] = []
    at = 0
    for packed in values:
        start = command.find(packed, at)
        if start < 0:  # not where msgpack writes it (cannot happen for umsgpack's own bytes): keep the command whole
            return [command]
        pieces += [command[at:start], packed]
        at = start + len(packed)
    pieces.append(command[at:])
    return [index.setdefault(p, len(index)) if i % 2 else p for i, p in enumerate(pieces) if p]


def share_values(commands: Sequence[bytes], min_bytes: int = SHARE_MIN_BYTES) -> SharedCommands:
    """Return the msgpack `commands` with each value of `min_bytes` or more that they hold twice or more stored once.

    A value held once stays in its command. The values are found by decoding each command and looked up in
    its bytes, so every command joins back into exactly its bytes (`SharedCommands.joined`).
    """
    large = [list(_large_values(umsgpack.unpackb(c), min_bytes)) for c in commands]
    count = Counter(v for values in large for v in values)
    index: dict[bytes, int] = {}
    pieces = [_cut(c, [v for v in values if count[v] > 1], index) for c, values in zip(commands, large)]
    return SharedCommands(values=list(index), commands=pieces)


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


#: The page's glue: ``b64`` decodes one base64 string, ``joinPieces`` concatenates pieces (base64, or an index
#: in ``sharedValues``).
_REPLAY_JS = """function b64(s) { const b = atob(s); const a = new Uint8Array(b.length);
  for (let i = 0; i < b.length; i++) a[i] = b.charCodeAt(i); return a; }
const sharedValues = [__SHARED__];
function joinPieces(parts) {
  const bytes = parts.map(function (p) { return typeof p === "number" ? sharedValues[p] : b64(p); });
  const out = new Uint8Array(bytes.reduce(function (n, b) { return n + b.length; }, 0));
  let at = 0;
  for (const b of bytes) { out.set(b, at); at += b.length; }
  return out;
}
"""


def replay_js(commands: Sequence[bytes], min_bytes: int = SHARE_MIN_BYTES) -> str:
    """Return the page's JavaScript replaying `commands` into ``viewer``, each distinct large value written once.

    A command without large values is ``viewer.handle_command_bytearray(b64("..."))``; one with them is
    ``viewer.handle_command_bytearray(joinPieces(["...", 0, "..."]))``, the numbers indexing ``sharedValues``.
    """
    shared = share_values(commands, min_bytes)
    table = ",\n".join(f'b64("{_b64(v)}")' for v in shared.values)
    calls = []
    for pieces in shared.commands:
        if len(pieces) == 1 and isinstance(pieces[0], bytes):
            calls.append(f'viewer.handle_command_bytearray(b64("{_b64(pieces[0])}"));\n')
        else:
            parts = ", ".join(str(p) if isinstance(p, int) else f'"{_b64(p)}"' for p in pieces)
            calls.append(f"viewer.handle_command_bytearray(joinPieces([{parts}]));\n")
    return _REPLAY_JS.replace("__SHARED__", table) + "".join(calls)
