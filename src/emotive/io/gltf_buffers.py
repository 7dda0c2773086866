"""A glTF document's buffers and accessors, every size checked before any array is made.

A buffer is the GLB's binary chunk, a base64 ``data:`` URI inside the JSON, or a file the
``uri`` names, which must lie in the document's folder (:func:`~emotive.io.input_limits.
resolve_reference`, after percent-decoding and resolving symbolic links) and be a regular
file (:func:`~emotive.io.input_limits.open_regular`); URLs are never fetched. Files are read
by range: only the bytes an accessor needs, never a whole ``.bin`` of meshes.

An accessor's ``count``, ``byteOffset``, its buffer view's ``byteOffset``, ``byteLength``
and ``byteStride`` and the buffer's ``byteLength`` are checked against each other and against
the bytes really there before anything is read, and the values all accessors hold together
against ``MAX_VALUES``, so no declared size makes a large array. Values must be finite.
"""

from __future__ import annotations

import os

import numpy as np
import pygltflib as gl

from emotive.io import input_limits
from emotive.io.gltf_document import CORRUPT, Document
from emotive.io.input_limits import (
    InputFile,
    decode_data_uri,
    open_regular,
    quote,
    resolve_reference,
)

_COMPONENT_DTYPES = {gl.BYTE: np.int8, gl.UNSIGNED_BYTE: np.uint8, gl.SHORT: np.int16,
                     gl.UNSIGNED_SHORT: np.uint16, gl.UNSIGNED_INT: np.uint32,
                     gl.FLOAT: np.float32}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
#: Largest ``byteStride`` glTF allows, bytes.
_MAX_STRIDE = 252
_BESIDE = "keep the .bin beside the .gltf (or in a folder below it), or export a .glb"


class Buffers:
    """The buffers of a document, read by range, and the values of its accessors.

    Close it (it is a context manager) to close the buffer files it opened.

    Args:
        doc: the document.
    """

    def __init__(self, doc: Document) -> None:
        self.doc = doc
        self._sizes: dict[int, int] = {}
        self._data: dict[int, bytes] = {}
        self._files: dict[int, InputFile] = {}
        self._values: dict[int, np.ndarray] = {}
        #: Values of every accessor read so far (count x width).
        self.values_read = 0

    def __enter__(self) -> Buffers:
        return self

    def __exit__(self, *exc: object) -> None:
        for file in self._files.values():
            file.close()
        self._files.clear()

    def _size(self, index: int) -> int:
        """Bytes of buffer ``index`` (its ``byteLength``), its data found and checked."""
        if index in self._sizes:
            return self._sizes[index]
        doc = self.doc
        where, buffer = doc.entry("buffers", index, f"buffers[{index}]")
        length = doc.integer(buffer, "byteLength", where, low=1,
                             high=input_limits.MAX_FILE_BYTES,
                             fix="split the clip or export less")
        uri = doc.string(buffer, "uri", where)
        if uri is None:
            have = self._glb_chunk(index, where)
        elif uri.startswith("data:"):
            self._data[index] = decode_data_uri(uri, lambda p: doc.fail(f"{where}.uri", p))
            have = len(self._data[index])
        else:
            have = self._open(index, where, uri).size
        if have < length:
            raise doc.fail(f"{where}.byteLength", f"is {length:,} bytes, but its data holds "
                           f"{have:,}; the file is truncated or corrupt")
        self._sizes[index] = length
        return length

    def _glb_chunk(self, index: int, where: str) -> int:
        chunk = self.doc.bin_chunk
        if index != 0 or chunk is None:
            raise self.doc.fail(where, "has no data (no uri and no GLB binary chunk); "
                                f"{CORRUPT}")
        return chunk[1]

    def _open(self, index: int, where: str, uri: str) -> InputFile:
        doc = self.doc
        real = resolve_reference(doc.folder, uri, lambda p: doc.fail(f"{where}.uri", p))

        # Named from the document's folder, which the message's file path already gives:
        # a long absolute path would be cut by quote() just before the name that matters.
        name = os.path.relpath(real, os.path.realpath(doc.folder))

        def fail(problem: str) -> Exception:
            return doc.fail(f"{where}.uri", f"cannot read the buffer file {quote(name)} "
                            f"beside it ({problem}); {_BESIDE}")

        self._files[index] = open_regular(real, fail, inside=doc.folder)
        return self._files[index]

    def read(self, index: int, offset: int, length: int) -> bytes:
        """``length`` bytes from ``offset`` of buffer ``index`` (checked by the caller)."""
        if index in self._data:
            return self._data[index][offset:offset + length]
        if index in self._files:
            return self._files[index].read_at(offset, length)
        return self.doc.file.read_at(self.doc.bin_chunk[0] + offset, length)

    def accessor(self, index: object, element: str) -> np.ndarray:
        """``(count, width)`` float64 values of an accessor (normalized integers scaled).

        Args:
            index: the accessor's index, as the document gives it.
            element: what refers to it (``"animations[0].samplers[2].input"``).

        Raises:
            MotionFileError: the accessor, its view or its buffer is missing, malformed,
                reads past the data there, would take the values read beyond
                ``MAX_VALUES``, or holds values that are not finite.
        """
        doc = self.doc
        where, acc = doc.entry("accessors", index, element)
        if index in self._values:
            return self._values[index]
        component = doc.integer(acc, "componentType", where)
        kind = doc.string(acc, "type", where)
        dtype, width = _COMPONENT_DTYPES.get(component), _WIDTHS.get(kind)
        if dtype is None or width is None:
            raise doc.fail(where, f"is of type {_text(kind)} with component type "
                           f"{component}, which animations do not use; re-export it")
        if acc.get("sparse") is not None:
            raise doc.fail(f"{where}.sparse", "is a sparse accessor, which emotive does not "
                           "read; re-export the file without sparse accessors (e.g. from "
                           "Blender)")
        normalized = doc.boolean(acc, "normalized", where)
        if dtype is not np.float32 and not normalized:
            raise doc.fail(f"{where}.normalized", "is false for integers, which glTF does not "
                           "allow for animation data (not normalized); re-export it")
        count = doc.integer(acc, "count", where, low=1, high=input_limits.MAX_VALUES,
                            fix="split the clip")
        total = self.values_read + count * width
        if total > input_limits.MAX_VALUES:
            raise doc.fail(f"{where}.count", f"is {count:,}: with the accessors read before, "
                           f"{total:,} values, at most {input_limits.MAX_VALUES:,} are read; "
                           "split the clip")
        view = acc.get("bufferView")
        if view is None:
            values = np.zeros((count, width))
        else:
            values = self._view(acc, where, view, np.dtype(dtype), width, count)
        self.values_read = total
        if dtype is not np.float32:
            values = np.maximum(values / np.iinfo(dtype).max, -1.0)
        if not np.all(np.isfinite(values)):
            raise doc.fail(where, "holds values that are not finite numbers (NaN or "
                           f"infinite); {CORRUPT}")
        self._values[index] = values
        return values

    def _view(self, acc: dict, where: str, view_index: object, dtype: np.dtype, width: int,
              count: int) -> np.ndarray:
        """``(count, width)`` float64 values an accessor reads from its buffer view."""
        doc = self.doc
        vwhere, view = doc.entry("bufferViews", view_index, f"{where}.bufferView")
        most = input_limits.MAX_FILE_BYTES
        buffer = doc.integer(view, "buffer", vwhere)
        start = doc.integer(view, "byteOffset", vwhere, default=0, high=most)
        length = doc.integer(view, "byteLength", vwhere, low=1, high=most)
        stride = doc.integer(view, "byteStride", vwhere, default=None, low=4, high=_MAX_STRIDE)
        offset = doc.integer(acc, "byteOffset", where, default=0, high=most)
        item = dtype.itemsize * width
        if stride is not None and stride < item:
            raise doc.fail(f"{vwhere}.byteStride", f"is {stride}, less than the {item} bytes "
                           f"of one element of {where}; {CORRUPT}")
        stride = stride or item
        span = stride * (count - 1) + item
        if offset + span > length:
            raise doc.fail(where, f"reads past the end of {vwhere}: {count:,} elements of "
                           f"{item} bytes {stride} apart from byteOffset {offset:,} need "
                           f"{offset + span:,} bytes, the view has {length:,}; the file is "
                           "truncated or corrupt")
        size = self._size(doc.index(buffer, f"{vwhere}.buffer", len(doc.array("buffers")),
                                    "buffers"))
        if start + length > size:
            raise doc.fail(vwhere, f"reads past the end of buffers[{buffer}]: byteOffset "
                           f"{start:,} + byteLength {length:,} > its {size:,} bytes; the file "
                           "is truncated or corrupt")
        data = self.read(buffer, start + offset, span)
        values = np.ndarray((count, width), dtype=dtype.newbyteorder("<"), buffer=data,
                            strides=(stride, dtype.itemsize))
        return values.astype(np.float64)


def _text(value: object) -> str:
    return quote(value) if isinstance(value, str) else str(value)
