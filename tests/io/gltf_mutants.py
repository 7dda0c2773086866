"""A deterministic fuzz corpus of hostile glTF/GLB files, and the process that reads it.

:func:`mutants` derives over 600 cases from a small walk written by the project's own writer
(:func:`emotive.io.gltf.gltf_document`, the shared rig of ``tests/rigs.py`` with its
skinned mannequin) as GLB, as ``.gltf`` with a data URI and as ``.gltf`` with a ``.bin``
beside it: buffer URIs that leave the folder (``../``, absolute paths, ``%2E%2E``, ``file:``
and ``http:`` URLs, symbolic links to files and folders outside, ``/etc/passwd``,
``/proc/self/environ``, ``/dev/zero``), FIFOs and folders where files belong, huge, negative
and ill-typed counts, offsets, strides and lengths, NaN, infinite and 3e38 values in node
transforms and in animation samples, cycles, a 100,023-node chain and other node graphs at
and beyond the limits, broken GLB containers and JSON, then seeded byte flips, truncations
and field swaps. Nothing is committed: the corpus is rebuilt from a fixed seed on every run.

Each case is written into a folder of its own (:func:`write_case`); a folder beside the cases
(:data:`OUTSIDE`) holds a sentinel whose bytes are a valid buffer for every case, so a reader
that followed a reference out of its folder would build a motion from it. :func:`worker`
reads a batch of cases in a process held to :data:`ADDRESS_SPACE` bytes, auditing every
file it opens, and prints one JSON line per case.
"""

from __future__ import annotations

import copy
import json
import os
import struct
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: The folder beside the case folders that no case may read from.
OUTSIDE = "outside"
#: The sentinel in :data:`OUTSIDE`: the base walk's buffer, valid for every case.
SENTINEL = "outside.bin"
#: Placeholder for the absolute path of :data:`OUTSIDE` in a case's bytes.
HERE = "@OUTSIDE@"
#: Address-space limit of the reading process (``RLIMIT_AS``), bytes.
ADDRESS_SPACE = 2 * 1024**3
#: Nodes in the chain of the hardening campaign's slow file.
CHAIN_NODES = 100_023

_SEED = 20_240_611
_RELAXED = "any"
_READ = "read"


@dataclass
class Mutant:
    """One case: its document and the files, links and FIFOs beside it.

    Attributes:
        name: unique name (also its folder's).
        main: the document's file name.
        json: the document's JSON object (encoded when written), unless ``raw`` is given.
        binary: the GLB binary chunk; ``None`` writes a ``.gltf`` JSON file.
        raw: the document's bytes as they are (byte-level mutants).
        files: other files in the case folder, by relative name.
        links: symbolic links in the case folder: name -> target (:data:`HERE` expands).
        fifos: FIFOs made in the case folder (the document's own name makes it one).
        expect: ``"any"`` (read or refused), ``"read"``, or text every refusal must contain
            (the element it names).
    """

    name: str
    main: str
    json: dict | None = None
    binary: bytes | None = None
    raw: bytes | None = None
    files: dict[str, bytes] = field(default_factory=dict)
    links: dict[str, str] = field(default_factory=dict)
    fifos: tuple[str, ...] = ()
    expect: str = _RELAXED
    sparse_size: int = 0


def base() -> tuple[dict, bytes]:
    """The JSON object and buffer of the base walk (skin, mannequin, 5 frames at 30 fps)."""
    from bvh_mutants import base_motion

    from emotive.io.gltf import gltf_document

    doc, blob = gltf_document(base_motion(), mesh=True)
    return json.loads(doc.gltf_to_json(separators=(",", ":"))), blob


def glb_bytes(root: dict, binary: bytes | None) -> bytes:
    """A GLB container of a JSON object and a binary chunk (padded as the format wants)."""
    text = json.dumps(root, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
    if binary is not None:
        binary += b"\0" * (-len(binary) % 4)
        chunks += struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks


def document_bytes(mutant: Mutant, outside: str) -> bytes:
    """The bytes of a case's document, :data:`HERE` replaced by ``outside``."""
    if mutant.raw is not None:
        return mutant.raw
    root = json.loads(json.dumps(mutant.json).replace(HERE, outside))
    if mutant.main.endswith(".glb"):
        return glb_bytes(root, mutant.binary)
    return json.dumps(root, separators=(",", ":")).encode()


def write_case(mutant: Mutant, folder: Path, outside: Path) -> Path:
    """Make a case's folder (document, files, links, FIFOs); returns the document's path."""
    folder.mkdir(parents=True)
    for name in mutant.fifos:
        os.mkfifo(folder / name)
    for name, data in mutant.files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)
    for name, target in mutant.links.items():
        os.symlink(target.replace(HERE, str(outside)), folder / name)
    path = folder / mutant.main
    if mutant.main not in mutant.fifos and mutant.main not in mutant.links and not (
            path.is_dir()):
        path.write_bytes(document_bytes(mutant, str(outside)))
        if mutant.sparse_size:
            os.truncate(path, mutant.sparse_size)
    return path


def make_outside(folder: Path, blob: bytes) -> Path:
    """The folder no case may read: the sentinel buffer, a FIFO and a folder."""
    folder.mkdir(parents=True)
    (folder / SENTINEL).write_bytes(blob)
    (folder / "walk.bin").write_bytes(blob)
    os.mkfifo(folder / "pipe.bin")
    (folder / "inner").mkdir()
    (folder / "inner" / SENTINEL).write_bytes(blob)
    return folder


# --- the corpus -----------------------------------------------------------------------------

#: Buffer URIs that lead out of the case folder, as a document writes them.
ESCAPES = (
    f"../{OUTSIDE}/{SENTINEL}", f"../../{OUTSIDE}/{SENTINEL}", f"{HERE}/{SENTINEL}",
    f"%2E%2E/{OUTSIDE}/{SENTINEL}", f"%2e%2e%2f{OUTSIDE}%2f{SENTINEL}",
    f"..%2F{OUTSIDE}%2F{SENTINEL}", f"sub/../../{OUTSIDE}/{SENTINEL}",
    f"./../{OUTSIDE}/{SENTINEL}", f"%252E%252E/{OUTSIDE}/{SENTINEL}",
    "/etc/passwd", "/proc/self/environ", "/dev/zero", "/dev/stdin", "/proc/self/fd/0",
    f"file://{HERE}/{SENTINEL}", "file:///etc/passwd", f"file:../{OUTSIDE}/{SENTINEL}",
    "http://127.0.0.1:9/walk.bin", "https://example.invalid/walk.bin", "ftp://x/walk.bin",
    "%2Fetc%2Fpasswd", "//etc/passwd", "\\\\server\\share\\walk.bin", "C:\\walk.bin",
    "C:/walk.bin", "walk.bin%00.png", "%ff%fe.bin", "", ".", "..", "/", f"../{OUTSIDE}",
    f"{'a/' * 3000}walk.bin", "~/walk.bin", f"../{OUTSIDE}/pipe.bin",
)
#: Symbolic links in a case folder and the URI that names them.
LINKS = (
    ("link.bin", f"../{OUTSIDE}/{SENTINEL}", "link.bin"),
    ("abs.bin", f"{HERE}/{SENTINEL}", "abs.bin"),
    ("zero.bin", "/dev/zero", "zero.bin"),
    ("env.bin", "/proc/self/environ", "env.bin"),
    ("passwd.bin", "/etc/passwd", "passwd.bin"),
    ("fifo.bin", f"{HERE}/pipe.bin", "fifo.bin"),
    ("sub", f"{HERE}/inner", f"sub/{SENTINEL}"),
    ("sub", "..", f"sub/{OUTSIDE}/{SENTINEL}"),
    ("loop.bin", "loop.bin", "loop.bin"),
)
#: Hostile values for whole-number fields.
HUGE_INTS = (-1, -(2**31), 2**31, 2**32, 2**53, 2**64, 10**400, 10**9, 1e9, 1.5, float("nan"),
             float("inf"), "3", True, [], {})
#: Hostile node transforms: (field, value).
TRANSFORMS = (
    ("matrix", [float("nan")] * 16), ("matrix", [float("inf")] + [0.0] * 15),
    ("matrix", [1e38, 0, 0, 0, 0, 1e38, 0, 0, 0, 0, 1e38, 0, 0, 0, 0, 1]),
    ("matrix", [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3e38, 0, 0, 1]), ("matrix", [0.0] * 16),
    ("matrix", [1, 0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]),
    ("matrix", [-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]), ("matrix", [1, 2, 3]),
    ("translation", [3e38, 0, 0]), ("translation", [1e38, 1e38, 1e38]),
    ("translation", [float("nan"), 0, 0]), ("translation", [10**400, 0, 0]),
    ("translation", [float("-inf"), 0, 0]), ("translation", ["0", 0, 0]),
    ("rotation", [0, 0, 0, 0]), ("rotation", [float("nan"), 0, 0, 1]),
    ("scale", [0, 0, 0]), ("scale", [1e38, 1e38, 1e38]), ("scale", [-1, 1, 1]),
    ("scale", [1e-30, 1e-30, 1e-30]), ("scale", [float("inf"), 1, 1]),
)
#: Hostile float32 values written into animation samples.
SAMPLES = (3e38, -3e38, 1e38, float("nan"), float("inf"), 1e30)
#: Hostile values any field may take (the seeded swaps).
SWAPS = (None, -1, 0, 1, 2**31, 10**30, 1e308, -1e308, float("nan"), float("inf"), "x", [],
         {}, True, [0] * 20, {"a": 1}, 0.5, -0.0)


def _copy(value: object) -> object:
    """A deep copy of a JSON value (faster than :func:`copy.deepcopy`)."""
    return json.loads(json.dumps(value))


def _case(name: str, root: dict, blob: bytes, kind: str, **kw) -> Mutant:
    """A case of ``root`` written as ``kind``: ``"glb"``, ``"data"`` (a data URI) or
    ``"bin"`` (``walk.bin`` beside it)."""
    import base64

    root = {**root, "buffers": _copy(root["buffers"])}
    files = dict(kw.pop("files", {}))
    if kind == "glb":
        return Mutant(name, "walk.glb", root, blob, files=files, **kw)
    if kind == "data" and root["buffers"][0].get("uri") is None:
        root["buffers"][0]["uri"] = ("data:application/octet-stream;base64,"
                                     + base64.b64encode(blob).decode())
    elif kind == "bin" and root["buffers"][0].get("uri") is None:
        root["buffers"][0]["uri"] = "walk.bin"
        files.setdefault("walk.bin", blob)
    return Mutant(name, "walk.gltf", root, files=files, **kw)


def _references(root: dict, blob: bytes) -> list[Mutant]:
    """URIs out of the folder, links, FIFOs, folders, and references the reader skips."""
    out = []
    for k, uri in enumerate(ESCAPES):
        for kind in ("bin", "glb"):
            doc = _copy(root)
            doc["buffers"][0]["uri"] = uri
            out.append(_case(f"escape_{kind}_{k}", doc, blob, kind, expect="buffers[0].uri"))
        doc = _copy(root)  # a second buffer holding the times
        doc["buffers"].append({"byteLength": len(blob), "uri": uri})
        doc["bufferViews"][0]["buffer"] = 1
        out.append(_case(f"escape_second_{k}", doc, blob, "data", expect="buffers[1].uri"))
        doc = _copy(root)  # an image the reader never needs: read, never opened
        doc["images"] = [{"uri": uri}]
        out.append(_case(f"image_{k}", doc, blob, "glb", expect=_READ))
    for k, (name, target, uri) in enumerate(LINKS):
        doc = _copy(root)
        doc["buffers"][0]["uri"] = uri
        out.append(_case(f"link_{k}", doc, blob, "bin", links={name: target},
                         expect="buffers[0].uri"))
    for name, uri, kw in (("fifo_buffer", "pipe.bin", {"fifos": ("pipe.bin",)}),
                          ("folder_buffer", "folder", {"files": {"folder/x": b""}}),
                          ("missing_buffer", "absent.bin", {})):
        doc = _copy(root)
        doc["buffers"][0]["uri"] = uri
        out.append(_case(name, doc, blob, "bin", expect="buffers[0].uri", **kw))
    inside = _copy(root)
    inside["buffers"][0]["uri"] = "data/walk%20data.bin"
    out.append(_case("below_folder", inside, blob, "bin", files={"data/walk data.bin": blob},
                     expect=_READ))
    out += [Mutant("main_fifo", "walk.gltf", fifos=("walk.gltf",), expect="not a regular"),
            Mutant("main_zero", "walk.glb", links={"walk.glb": "/dev/zero"},
                   expect="not a regular"),
            Mutant("main_environ", "walk.gltf", links={"walk.gltf": "/proc/self/environ"},
                   expect="system file"),
            Mutant("main_folder", "walk.gltf", files={"walk.gltf/x": b""}, expect="folder"),
            Mutant("main_missing", "walk.glb", raw=None, links={"walk.glb": "absent"},
                   expect="no such file")]
    return out


def _sizes(root: dict, blob: bytes) -> list[Mutant]:
    """Hostile counts, offsets, strides and lengths of accessors, views and buffers."""
    out = []
    fields = [("accessors", 0, key) for key in ("count", "byteOffset", "componentType",
                                                 "bufferView")]
    fields += [("accessors", 20, "count"), ("accessors", 1, "byteOffset")]
    fields += [("bufferViews", 0, key) for key in ("byteOffset", "byteLength", "byteStride",
                                                    "buffer")]
    fields += [("bufferViews", 20, "byteStride"), ("buffers", 0, "byteLength")]
    for array, index, key in fields:
        for k, value in enumerate(HUGE_INTS):
            doc = _copy(root)
            doc[array][index][key] = value
            kind = ("glb", "data", "bin")[k % 3]
            expect = f"{array}[{index}]" if array != "bufferViews" else "bufferViews["
            out.append(_case(f"size_{array}{index}_{key}_{k}", doc, blob, kind, expect=expect))
    for k, count in enumerate((10**9, 2**40, 25_000_000, 10**6)):
        doc = _copy(root)  # no bufferView: the reader would make zeros of count rows
        del doc["accessors"][20]["bufferView"]
        doc["accessors"][20]["count"] = count
        out.append(_case(f"zeros_{k}", doc, blob, "glb",
                         expect="accessors[20]" if count > 10**6 else _RELAXED))
    for k, (key, value) in enumerate((("type", "MAT4"), ("type", 7), ("normalized", 1),
                                      ("sparse", {"count": 10**9}),
                                      ("componentType", 5125))):
        doc = _copy(root)
        doc["accessors"][1][key] = value
        out.append(_case(f"accessor_kind_{k}", doc, blob, "glb", expect="accessors[1]"))
    return out


def _f32(blob: bytes, offset: int, value: float) -> bytes:
    data = bytearray(blob)
    data[offset:offset + 4] = np.array([value], dtype="<f4").tobytes()
    return bytes(data)


def _values(root: dict, blob: bytes) -> list[Mutant]:
    """Hostile node transforms and animation samples."""
    out = []
    for n in (0, 3, 19):  # the root joint, a middle joint, the mannequin (not a joint)
        for k, (key, value) in enumerate(TRANSFORMS):
            doc = _copy(root)
            node = doc["nodes"][n]
            if key == "matrix":  # a node has a matrix or translation, rotation and scale
                for other in ("translation", "rotation", "scale"):
                    node.pop(other, None)
            node[key] = value
            # A joint's huge scale shows in its children's offsets: any node may be named.
            expect = _READ if n == 19 else "nodes["
            out.append(_case(f"node{n}_{key}_{k}", doc, blob, ("glb", "data")[k % 2],
                             expect=expect))
    times, translations = root["bufferViews"][0], root["bufferViews"][20]
    for k, value in enumerate(SAMPLES):
        places = [("translation", translations["byteOffset"] + 12 * 2,
                   "nodes[0]" if np.isfinite(value) else "accessors[20]"),
                  ("time", times["byteOffset"] + 4 * 4, "accessors[0]"),
                  ("rotation", root["bufferViews"][3]["byteOffset"] + 16 + 4,
                   "accessors[3]")]
        for what, offset, element in places:
            finite = np.isfinite(value)
            if what == "rotation" and finite:
                element = _RELAXED  # a large quaternion component normalizes to a rotation
            elif what == "time" and finite:
                element = "animations[0]" if value > 1e6 else "animations[0].samplers"
            out.append(_case(f"sample_{what}_{k}", root, _f32(blob, offset, value), "glb",
                             expect=element))
    doc = _copy(root)
    doc["nodes"].append({"name": "Armature", "children": [0], "scale": [1e30, 1e30, 1e30]})
    doc["scenes"][0]["nodes"] = [len(doc["nodes"]) - 1, 19]
    out.append(_case("armature_scale", doc, blob, "glb", expect="nodes["))
    return out


def _graphs(root: dict, blob: bytes) -> list[Mutant]:
    """Cycles, shared children, chains and crowds at and beyond the node limits."""
    from emotive.io import input_limits as limits

    out = []
    edits = {
        "cycle": lambda d: d["nodes"][4].update(children=[0]),
        "self_child": lambda d: d["nodes"][2].update(children=[2]),
        "two_parents": lambda d: d["nodes"][5].update(children=[6, 1]),
        "child_missing": lambda d: d["nodes"][0].update(children=[1, 999_999]),
        "child_negative": lambda d: d["nodes"][0].update(children=[-1]),
        "child_text": lambda d: d["nodes"][0].update(children=["1"]),
        "children_object": lambda d: d["nodes"][0].update(children={"a": 1}),
        "node_list": lambda d: d["nodes"].__setitem__(3, [1, 2]),
        "nodes_object": lambda d: d.update(nodes={"0": {}}),
        "skin_missing_joint": lambda d: d["skins"][0]["joints"].append(10**12),
        "skin_many_joints": lambda d: d["skins"][0].update(joints=list(range(20)) * 60),
        "skin_empty": lambda d: d["skins"][0].update(joints=[]),
        "name_long": lambda d: d["nodes"][1].update(name="n" * 5000),
        "name_number": lambda d: d["nodes"][1].update(name=12),
    }
    for name, edit in edits.items():
        doc = _copy(root)
        edit(doc)
        out.append(_case(f"graph_{name}", doc, blob, "glb",
                         expect="skins[0]" if name.startswith("skin") else "nodes"))

    def chain(extra: int, deep: bool) -> dict:
        """The walk under a chain of ``extra`` nodes (``deep``), or beside as many roots."""
        doc = _copy(root)
        first = len(doc["nodes"])
        if deep:
            doc["nodes"] += [{"children": [first + k + 1]} for k in range(extra - 1)]
            doc["nodes"].append({"children": [0]})
            doc["scenes"][0]["nodes"] = [first, 19]
        else:
            doc["nodes"] += [{} for _ in range(extra)]
        return doc

    out.append(_case("chain_campaign", chain(CHAIN_NODES - 20, True), blob, "glb",
                     expect="nodes"))
    out.append(_case("chain_too_deep", chain(limits.MAX_DEPTH, True), blob, "glb",
                     expect="nested"))
    # The walk's own joints nest 6 deep (Hips, Spine, Chest, UpperArm, LowerArm, Hand).
    out.append(_case("chain_deepest", chain(limits.MAX_DEPTH - 6, True), blob, "glb",
                     expect=_READ))
    out.append(_case("crowd_too_many", chain(limits.MAX_NODES - 19, False), blob, "glb",
                     expect="nodes"))
    out.append(_case("crowd_most", chain(limits.MAX_NODES - 20, False), blob, "glb",
                     expect=_READ))
    return out


def _containers(root: dict, blob: bytes) -> list[Mutant]:
    """Broken GLB headers and chunks, JSON that is not a document, sizes over the budgets."""
    from emotive.io import input_limits as limits

    good = glb_bytes(root, blob)
    text = json.dumps(root, separators=(",", ":")).encode()
    raw = {
        "glb_version1": good[:4] + struct.pack("<I", 1) + good[8:],
        "glb_length_long": good[:8] + struct.pack("<I", len(good) + 100) + good[12:],
        "glb_length_short": good[:8] + struct.pack("<I", 16) + good[12:],
        "glb_chunk_huge": good[:12] + struct.pack("<I", 2**32 - 1) + good[16:],
        "glb_no_json": good[:16] + b"XXXX" + good[20:],
        "glb_header_only": good[:12], "glb_cut": good[:7], "empty": b"",
        "json_nested": b"[" * 200_000 + b"]" * 200_000,
        "json_commas": b"[" + b"0," * 5_000_000 + b"0]",
        "json_list": b"[1, 2, 3]", "json_latin1": text.replace(b'"Hips"', b'"H\xe9ps"'),
        "json_big_int": text.replace(b'"count":5', b'"count":' + b"9" * 5000, 1),
        "json_nan_literal": text.replace(b'"count":5', b'"count":NaN', 1),
        "json_gltf1": text.replace(b'"version":"2.0"', b'"version":"1.0"'),
        "json_extension": text[:-1] + b',"extensionsRequired":["EXT_meshopt_compression"]}',
    }
    out = [Mutant(name, "walk.glb" if name.startswith("glb") else "walk.gltf", raw=data,
                  expect="walk.") for name, data in raw.items()]
    no_bin = _copy(root)
    out.append(Mutant("glb_no_bin", "walk.glb", no_bin, None, expect="buffers[0]"))
    out.append(Mutant("gltf_too_big", "walk.gltf", raw=text, sparse_size=limits.MAX_JSON_BYTES
                      + 1, expect="at most"))
    out.append(Mutant("glb_too_big", "walk.glb", raw=good,
                      sparse_size=limits.MAX_FILE_BYTES + 1, expect="at most"))
    return out


def _paths(value: object, prefix: tuple = ()) -> list[tuple]:
    """Every path of keys and indices into a JSON value (long lists: their first items)."""
    out = [prefix]
    if isinstance(value, dict):
        for key, item in value.items():
            out += _paths(item, (*prefix, key))
    elif isinstance(value, list):
        for k, item in enumerate(value[:3]):
            out += _paths(item, (*prefix, k))
    return out


def _random(root: dict, blob: bytes, rng: np.random.Generator) -> list[Mutant]:
    """Seeded byte flips, truncations and field swaps."""
    out = []
    glb = glb_bytes(root, blob)
    text = json.dumps(root, separators=(",", ":")).encode()
    json_end = 20 + struct.unpack("<I", glb[12:16])[0]
    for k in range(120):
        data = bytearray(glb if k % 2 else text)
        top = json_end if k % 4 == 1 else len(data)  # some flips in the GLB's JSON only
        for at in rng.integers(0, top, int(rng.integers(1, 6))):
            data[at] = int(rng.integers(0, 256))
        out.append(Mutant(f"flip_{k}", "walk.glb" if k % 2 else "walk.gltf", raw=bytes(data)))
    for k in range(30):
        data = glb if k % 2 else text
        out.append(Mutant(f"cut_{k}", "walk.glb" if k % 2 else "walk.gltf",
                          raw=data[:int(rng.integers(0, len(data)))]))
    paths = [p for p in _paths(root) if p and p[0] != "buffers"]
    for k in range(150):
        doc = _copy(root)
        path = paths[int(rng.integers(0, len(paths)))]
        holder = doc
        for key in path[:-1]:
            holder = holder[key]
        holder[path[-1]] = copy.deepcopy(SWAPS[int(rng.integers(0, len(SWAPS)))])
        out.append(_case(f"swap_{k}", doc, blob, ("glb", "data", "bin")[k % 3]))
    return out


def mutants() -> list[Mutant]:
    """The whole corpus, the same on every run."""
    root, blob = base()
    rng = np.random.default_rng(_SEED)
    corpus = [_case(f"base_{kind}", root, blob, kind, expect=_READ)
              for kind in ("glb", "data", "bin")]
    for family in (_references, _sizes, _values, _graphs, _containers):
        corpus += family(root, blob)
    return corpus + _random(root, blob, rng)


# --- the reading process --------------------------------------------------------------------

def _allowed(real: str, roots: tuple[str, ...]) -> bool:
    return any(real == r or real.startswith(r + os.sep) for r in roots)


def worker() -> None:
    """Read the cases listed in the JSON file ``sys.argv[1]`` and print one JSON line each.

    The process is held to :data:`ADDRESS_SPACE` bytes of address space before anything is
    imported. Every ``open`` (``io.open`` and ``os.open``) of a path outside the case's folder
    and outside the interpreter's own files is recorded, as is any network call; a line
    ``{"start": name}`` before each case names the one a hang stopped in.
    """
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))
    import time

    from emotive.errors import MotionFileError
    from emotive.io import input_limits as limits
    from emotive.io.gltf_read import read_gltf

    batch = json.loads(Path(sys.argv[1]).read_text())
    read_gltf(batch["warmup"])  # lazy imports happen before the audit starts
    trusted = tuple(os.path.realpath(p) for p in {sys.prefix, sys.base_prefix,
                                                  sys.exec_prefix, *batch["trusted"]})
    state: dict = {"folder": "", "outside": []}

    def audit(event: str, args: tuple) -> None:
        if event == "open" and isinstance(args[0], str | bytes | os.PathLike):
            real = os.path.realpath(os.fsdecode(args[0]))
            if not _allowed(real, (state["folder"], *trusted)):
                state["outside"].append(real)
        elif event.startswith(("socket.", "urllib.")):
            state["outside"].append(f"{event} {args[:2]!r}")

    sys.addaudithook(audit)
    for case in batch["cases"]:
        print(json.dumps({"start": case["name"]}), flush=True)
        state["folder"], state["outside"] = os.path.realpath(case["folder"]), []
        result = {"name": case["name"], "path": case["path"], "outcome": "read", "message": ""}
        start = time.process_time()
        try:
            motion = read_gltf(case["path"])
        except MotionFileError as exc:
            result.update(outcome="refused", message=str(exc))
        except BaseException as exc:  # what the fuzz counts: never a crash of another type
            result.update(outcome="crash", message=f"{type(exc).__name__}: {exc}"[:500])
        else:
            result["plausible"] = bool(
                motion.skeleton.num_joints <= limits.MAX_JOINTS
                and motion.num_frames <= limits.MAX_FRAMES
                and limits.MIN_FPS <= motion.fps <= limits.MAX_FPS
                and all(np.isfinite(a).all() for a in (motion.rotations, motion.positions,
                                                       motion.skeleton.offsets))
                and np.abs(motion.positions).max() <= limits.MAX_LENGTH_M
                and np.abs(motion.skeleton.offsets).max() <= limits.MAX_LENGTH_M)
        result["cpu_s"] = time.process_time() - start
        result["outside"] = state["outside"][:5]
        print(json.dumps(result), flush=True)


if __name__ == "__main__":
    worker()
