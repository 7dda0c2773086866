"""A glTF document read within the input contract: its container and its typed fields.

:func:`open_document` opens a ``.glb`` or ``.gltf`` file (told apart by its first bytes) with
:func:`emotive.io.input_limits.open_regular`, finds the GLB's chunks, parses the JSON (at
most ``MAX_JSON_BYTES``, at most ``MAX_JSON_ITEMS`` values, counted before it is parsed) and
gives a :class:`Document`: the JSON as parsed, the place of the
GLB's binary chunk (read later, by range, :mod:`emotive.io.gltf_buffers`) and typed reads of
its fields. Each read checks the field's type and range and raises a
:class:`~emotive.errors.MotionFileError` that names the file, the element (``accessors[3].count``)
and the fix.

The JSON is not decoded into objects: pygltflib's dataclass decoding took 0.5 ms a node (52 s
for a 100,000-node chain), so only the fields the reader needs are read, when it needs them.
"""

from __future__ import annotations

import json
import math
import os
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from emotive.errors import MotionFileError
from emotive.io import input_limits
from emotive.io.input_limits import InputFile, open_regular, quote

#: Extensions that change how buffers or animations are stored, which this reader cannot read.
UNSUPPORTED_EXTENSIONS = ("EXT_meshopt_compression", "KHR_animation_pointer")

#: Fix of a file whose structure is broken.
CORRUPT = "the file is corrupt, export it again"

#: Most chunks of a GLB container looked at (the format has two: JSON and BIN).
MAX_GLB_CHUNKS = 16

_GLB_MAGIC = b"glTF"
_JSON_CHUNK = 0x4E4F534A
_BIN_CHUNK = 0x004E4942
_REQUIRED = object()
_UNREADABLE = "not a readable glTF file"


class Document:
    """A parsed glTF document: its JSON and typed, bounded reads of its fields.

    Args:
        path: the file, as the caller named it (for messages).
        file: the open file (the GLB's binary chunk is read from it).
        root: the parsed JSON object.
        bin_chunk: ``(offset, length)`` of the GLB's binary chunk in the file, or ``None``.
    """

    def __init__(self, path: Path, file: InputFile, root: dict,
                 bin_chunk: tuple[int, int] | None) -> None:
        self.path = path
        self.file = file
        self.root = root
        self.bin_chunk = bin_chunk
        #: Real path of the file's folder: the only place its references may lead.
        self.folder = os.path.dirname(file.path)

    def fail(self, element: str, problem: str) -> MotionFileError:
        """The error for ``element`` (``"accessors[3].count"``) and its problem and fix."""
        return MotionFileError(self.path, f"{element}: {problem}")

    def array(self, name: str) -> list:
        """A top-level array (``"nodes"``), empty when absent, at most ``MAX_NODES`` long."""
        value = self.root.get(name)
        if value is None:
            return []
        if not isinstance(value, list):
            raise self.fail(name, f"is {_kind(value)}, not a list; {CORRUPT}")
        if len(value) > input_limits.MAX_NODES:
            raise self.fail(name, f"holds {len(value):,} entries: at most "
                            f"{input_limits.MAX_NODES:,} are read; simplify the scene")
        return value

    def entry(self, name: str, index: object, element: str) -> tuple[str, dict]:
        """``(where, object)`` of entry ``index`` of array ``name``, which ``element`` names."""
        items = self.array(name)
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(items):
            raise self.fail(element, f"refers to {name}[{_short(index)}], which is not there "
                            f"({len(items)} in the file); {CORRUPT}")
        where = f"{name}[{index}]"
        return where, self.obj(items[index], where)

    def obj(self, value: object, where: str) -> dict:
        """``value``, which must be a JSON object."""
        if not isinstance(value, dict):
            raise self.fail(where, f"is {_kind(value)}, not an object; {CORRUPT}")
        return value

    def integer(self, obj: dict, key: str, where: str, default: object = _REQUIRED,
                low: int = 0, high: int | None = None, fix: str = CORRUPT) -> int | None:
        """A whole-number field within ``low``-``high`` (``default`` when absent or null).

        Args:
            obj: the JSON object.
            key: the field.
            where: the object's element name (``"accessors[3]"``).
            default: what an absent field reads as; absent and no default: an error.
            low: least value.
            high: largest value, ``None`` for none.
            fix: what the message says to do about a value out of range.
        """
        value = obj.get(key)
        if value is None:
            if default is _REQUIRED:
                raise self.fail(f"{where}.{key}", f"is missing; {CORRUPT}")
            return default  # type: ignore[return-value]
        if isinstance(value, float) and value.is_integer() and abs(value) < 2.0**53:
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(f"{where}.{key}", f"is {_short(value)}, not a whole number; "
                            f"{CORRUPT}")
        if value < low or (high is not None and value > high):
            top = "" if high is None else f" and at most {high:,}"
            raise self.fail(f"{where}.{key}", f"is {_short(value)}: it must be at least "
                            f"{low:,}{top}; {fix}")
        return value

    def string(self, obj: dict, key: str, where: str, default: str | None = None) -> str | None:
        """A text field (``default`` when absent or null)."""
        value = obj.get(key)
        if value is None:
            return default
        if not isinstance(value, str):
            raise self.fail(f"{where}.{key}", f"is {_kind(value)}, not text; {CORRUPT}")
        return value

    def boolean(self, obj: dict, key: str, where: str) -> bool:
        """A true/false field, false when absent."""
        value = obj.get(key, False)
        if not isinstance(value, bool):
            raise self.fail(f"{where}.{key}", f"is {_short(value)}, not true or false; "
                            f"{CORRUPT}")
        return value

    def numbers(self, obj: dict, key: str, where: str, length: int) -> list[float] | None:
        """``length`` finite numbers of a list field, ``None`` when absent or null."""
        value = obj.get(key)
        if value is None:
            return None
        if not isinstance(value, list) or len(value) != length:
            raise self.fail(f"{where}.{key}", f"must be a list of {length} numbers; {CORRUPT}")
        out = []
        for v in value:
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise self.fail(f"{where}.{key}", f"holds {_short(v)}, not a number; {CORRUPT}")
            try:
                v = float(v)
            except OverflowError:  # an integer beyond float64
                v = math.inf
            if not math.isfinite(v):
                raise self.fail(f"{where}.{key}", "holds a number that is not finite (NaN, "
                                f"infinite or beyond 1.8e308); {CORRUPT}")
            out.append(v)
        return out

    def indices(self, obj: dict, key: str, where: str) -> list:
        """A list field of indices, empty when absent.

        Its items are not checked here: :meth:`index` checks each where it is used, so a long
        list costs one pass.
        """
        value = obj.get(key)
        if value is None:
            return []
        if not isinstance(value, list):
            raise self.fail(f"{where}.{key}", f"is {_kind(value)}, not a list; {CORRUPT}")
        return value

    def index(self, value: object, element: str, size: int, name: str) -> int:
        """``value`` as an index into an array of ``size`` entries named ``name``."""
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < size:
            raise self.fail(element, f"refers to {name}[{_short(value)}], which is not there "
                            f"({size} in the file); {CORRUPT}")
        return value


def _kind(value: object) -> str:
    """``value``'s JSON kind with an article (``"a number"``)."""
    kinds = {dict: "an object", list: "a list", str: "text", bool: "true/false",
             int: "a number", float: "a number", type(None): "null"}
    return kinds.get(type(value), type(value).__name__)


def _short(value: object) -> str:
    """``value`` for a message, at most ``QUOTE_CHARS`` characters of it."""
    text = json.dumps(value) if not isinstance(value, int | float) else str(value)
    return quote(text) if len(text) > input_limits.QUOTE_CHARS else text


def _parse_json(data: bytes, fail: input_limits.Fail) -> dict:
    """The JSON object of ``data``, within ``MAX_JSON_ITEMS`` values."""
    items = data.count(b"{") + data.count(b"[") + data.count(b",")
    if items > input_limits.MAX_JSON_ITEMS:
        raise fail(f"{_UNREADABLE}: its JSON holds about {items:,} values: at most "
                   f"{input_limits.MAX_JSON_ITEMS:,} are read; simplify the scene or export "
                   "only the character")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise fail(f"{_UNREADABLE}: its JSON is not UTF-8 text; export it again as .glb or "
                   ".gltf") from None
    try:
        # NaN and Infinity are parsed as numbers: the typed reads refuse them, naming the
        # field that holds them.
        root = json.loads(text)
    except (ValueError, RecursionError) as exc:
        reason = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        raise fail(f"not a readable glTF file (JSON: {reason}); export it again as .glb or "
                   ".gltf") from None
    if not isinstance(root, dict):
        raise fail(f"not a readable glTF file: its JSON is {_kind(root)}, not an object; "
                   "export it again as .glb or .gltf")
    return root


def _glb_chunks(file: InputFile, fail: input_limits.Fail) -> tuple[bytes, tuple[int, int] | None]:
    """The JSON chunk's bytes and ``(offset, length)`` of the binary chunk of a GLB file."""
    if file.size < 20:
        raise fail(f"{_UNREADABLE}: a GLB file of {file.size} bytes is too short for its header; "
                   f"{CORRUPT}")
    _, version, length = struct.unpack("<4sII", file.read_at(0, 12))
    if version != 2:
        raise fail(f"{_UNREADABLE}: a GLB file of version {version} (emotive reads glTF 2.0); "
                   "convert it (import and export it in Blender)")
    if not 20 <= length <= file.size:
        raise fail(f"{_UNREADABLE}: its GLB header gives a length of {length:,} bytes, but the "
                   f"file holds {file.size:,}; the file is truncated or corrupt")
    offset, text, binary = 12, None, None
    for _ in range(MAX_GLB_CHUNKS):
        if offset + 8 > length or (text is not None and binary is not None):
            break
        size, kind = struct.unpack("<II", file.read_at(offset, 8))
        offset += 8
        if size > length - offset:
            raise fail(f"{_UNREADABLE}: a GLB chunk at byte {offset - 8:,} claims {size:,} "
                       f"bytes, past the end of the file ({length:,} bytes); the file is "
                       "truncated or corrupt")
        if kind == _JSON_CHUNK and text is None:
            if size > input_limits.MAX_JSON_BYTES:
                raise fail(f"{_UNREADABLE}: its JSON chunk is {size:,} bytes, at most "
                           f"{input_limits.MAX_JSON_BYTES:,} are read; simplify the scene")
            text = file.read_at(offset, size)
        elif kind == _BIN_CHUNK and binary is None:
            binary = (offset, size)
        offset += size
    if text is None:
        raise fail(f"{_UNREADABLE}: its GLB container holds no JSON chunk; {CORRUPT}")
    return text, binary


def _check_root(doc: Document) -> None:
    """Refuse a document of another glTF version or needing an unsupported extension."""
    asset = doc.root.get("asset")
    if isinstance(asset, dict):
        version = asset.get("version")
        if isinstance(version, str) and not version.startswith("2"):
            raise doc.fail("asset.version", f"is {quote(version)}: emotive reads glTF 2.0; "
                           "convert the file (import and export it in Blender)")
    required = doc.root.get("extensionsRequired") or []
    if not isinstance(required, list):
        raise doc.fail("extensionsRequired", f"is {_kind(required)}, not a list; {CORRUPT}")
    for name in required:
        if name in UNSUPPORTED_EXTENSIONS:
            raise doc.fail("extensionsRequired", f"needs the glTF extension {name}, which "
                           "emotive does not read; re-export the file without compression")


@contextmanager
def open_document(path: str | os.PathLike) -> Iterator[Document]:
    """The document of a ``.glb`` or ``.gltf`` file, open while the context lasts.

    Raises:
        MotionFileError: the file is not a regular file within ``MAX_FILE_BYTES`` (a
            ``.gltf`` within ``MAX_JSON_BYTES``), or not a readable glTF 2.0 container.
    """
    path = Path(path)

    def fail(problem: str) -> MotionFileError:
        return MotionFileError(path, problem)

    with open_regular(path, fail) as file:
        if file.read_at(0, min(file.size, 4)) == _GLB_MAGIC:
            text, binary = _glb_chunks(file, fail)
        else:
            if file.size > input_limits.MAX_JSON_BYTES:
                raise fail(f"is a {file.size:,}-byte glTF JSON file: at most "
                           f"{input_limits.MAX_JSON_BYTES:,} are read; export it as .glb")
            text, binary = file.read_all(), None
        doc = Document(path, file, _parse_json(text, fail), binary)
        del text
        _check_root(doc)
        yield doc

