"""CDR bytes <-> numpy columns for the big gnss_sim messages, without Python message objects.

rclpy builds one Python object per satellite and per nested Point (SatelliteStates: 4 objects per
satellite, 500 per epoch) and the middleware serialises them again; at 10 Hz that was most of an
epoch's CPU in the composed graph. Here a message is laid out straight between the CDR bytes that
travel (rclpy ``publish(bytes)``, ``create_subscription(..., raw=True)``) and numpy columns: one
array per field of a sequence of structures, nested sequences as counts + flat columns.

The encoding is what rmw_fastrtps writes (classic CDR, XCDR1, little endian; DDS-XTypes 1.3 7.4.1
"CDR (Version 1)" and the OMG CDR of CORBA 15.3): a 4-byte encapsulation header (0x00 0x01 0x00 0x00:
CDR_LE), then every primitive aligned to its own size counted from the end of that header; a string
is a uint32 length (NUL included), its bytes and the NUL; a sequence is a uint32 count and its
elements (the first one aligned only when there is one); a nested structure adds no alignment of
its own. The output is padded with zeros to a multiple of 4 bytes (rosbags reads at most 3 bytes
past the end). test/test_cdr_codec.py checks every byte that is not padding against rclpy's
serialize_message, and the decoding against deserialize_message, for the messages used here.

A schema is a tuple of fields ``(name, kind)``: kind is a numpy type code of a primitive ("f8",
"f4", "u1", "i1", "u2", "i2", "u4", "i4", "b1" bool), "str", a tuple (a nested structure: its
fields flattened into "name.field" columns), or ``("seq", element)`` with element a type code or a
schema (a sequence). Big-endian or malformed bytes raise ``CdrError``; the caller falls back to
rclpy's deserialize_message (no ROS import here).
"""
from __future__ import annotations

import struct

import numpy as np

from gnss_sim_ros2.core.memo import BoundedCache

HEADER_LE = b"\x00\x01\x00\x00"
_SIZES = {"f8": 8, "f4": 4, "u1": 1, "i1": 1, "b1": 1, "u2": 2, "i2": 2, "u4": 4, "i4": 4, "u8": 8, "i8": 8}
_U32 = struct.Struct("<I")


class CdrError(ValueError):
    """Bytes this codec does not read (big endian, truncated, inconsistent lengths)."""


# ------------------------------------------------------------------ standard messages used
TIME = (("sec", "i4"), ("nanosec", "u4"))                       # builtin_interfaces/Time
HEADER = (("stamp", TIME), ("frame_id", "str"))                 # std_msgs/Header
XYZ = (("x", "f8"), ("y", "f8"), ("z", "f8"))                   # geometry_msgs/Point and Vector3


def _align(p: int, a: int) -> int:
    return (p + a - 1) & -a


class _Block:
    """A run of primitives with a fixed layout for each start offset modulo 8."""

    def __init__(self, fields: list[tuple[str, str]]):
        self.names = [n for n, _ in fields]
        self.codes = [c for _, c in fields]
        self.align = _SIZES[self.codes[0]]
        self.offsets = np.zeros((8, len(fields)), dtype=np.int64)   # [start % 8, field] -> offset from start
        self.sizes = [0] * 8
        for r in range(8):
            p = r
            for k, c in enumerate(self.codes):
                p = _align(p, _SIZES[c])
                self.offsets[r, k] = p - r
                p += _SIZES[c]
            self.sizes[r] = p - r
        self.dtypes = [np.dtype({"names": self.names, "formats": [_dtype(c) for c in self.codes],
                                 "offsets": [int(o) for o in self.offsets[r]], "itemsize": self.sizes[r]})
                       for r in range(8)]


class _Struct:
    """A schema compiled into steps: blocks of primitives, strings and sequences, in order."""

    def __init__(self, schema, prefix: str = ""):
        self.steps: list = []          # ("block", _Block) | ("str", name) | ("seq", name, _Struct | code)
        run: list = []
        for name, kind in _flatten(schema, prefix):
            if isinstance(kind, str) and kind in _SIZES:
                run.append((name, kind))
                continue
            if run:
                self.steps.append(("block", _Block(run)))
                run = []
            if kind == "str":
                self.steps.append(("str", name))
            else:
                elem = kind[1]
                self.steps.append(("seq", name, elem if isinstance(elem, str) else _Struct(elem)))
        if run:
            self.steps.append(("block", _Block(run)))
        self.flat = all(step[0] != "seq" for step in self.steps)
        self._templates: dict = {}
        self._fixed: dict = {}
        # a structure of primitives only, whose elements follow each other at one stride
        only = self.steps[0][1] if len(self.steps) == 1 and self.steps[0][0] == "block" else None
        self.uniform = only if only is not None and only.sizes[0] % only.align == 0 and max(
            _SIZES[c] for c in only.codes) == only.align else None


    def template(self, lengths: tuple):
        """(element size, offsets of the steps from the element's start) for each start offset modulo 8, of a
        flat structure whose strings have these lengths (NUL included)."""
        got = self._templates.get(lengths)
        if got is None:
            sizes, offs = [0] * 8, np.zeros((8, len(self.steps)), dtype=np.int64)
            for r in range(8):
                p, k = r, 0
                for j, step in enumerate(self.steps):
                    if step[0] == "block":
                        offs[r, j] = p - r
                        p += step[1].sizes[p & 7]
                    else:
                        p = (p + 3) & -4
                        offs[r, j] = p - r
                        p += 4 + lengths[k]
                        k += 1
                sizes[r] = p - r
            got = self._templates[lengths] = (sizes, offs)
        return got


    def fixed_template(self, lengths: tuple):
        """(element size, offsets of the steps, record dtype) for each start offset modulo 8 of an element whose
        strings have these lengths (NUL included) and whose sequences are empty: the whole element as one numpy
        record (fields: the primitives by name, a string's length word "<name>#len" and its bytes "<name>"
        (NUL included), a sequence's count "<name>#count")."""
        got = self._fixed.get(lengths)
        if got is None:
            sizes, offs, dtypes = [0] * 8, np.zeros((8, len(self.steps)), dtype=np.int64), []
            for r in range(8):
                p, k = r, 0
                names, formats, offsets = [], [], []
                for j, step in enumerate(self.steps):
                    if step[0] == "block":
                        b, q = step[1], p & 7
                        offs[r, j] = p - r
                        names += b.names
                        formats += [_dtype(c) for c in b.codes]
                        offsets += [p - r + int(o) for o in b.offsets[q]]
                        p += b.sizes[q]
                        continue
                    p = (p + 3) & -4
                    offs[r, j] = p - r
                    if step[0] == "str":
                        length = lengths[k]
                        k += 1
                        names += [step[1] + "#len", step[1]]
                        formats += ["<u4", ("u1", (length,))]
                        offsets += [p - r, p - r + 4]
                        p += 4 + length
                    else:
                        names.append(step[1] + "#count")
                        formats.append("<u4")
                        offsets.append(p - r)
                        p += 4
                sizes[r] = p - r
                dtypes.append(np.dtype({"names": names, "formats": formats, "offsets": offsets,
                                        "itemsize": p - r}))
            got = self._fixed[lengths] = (sizes, offs, dtypes)
        return got


def _flatten(schema, prefix: str):
    for name, kind in schema:
        if isinstance(kind, tuple) and kind and kind[0] != "seq":
            yield from _flatten(kind, f"{prefix}{name}.")
        else:
            yield f"{prefix}{name}", kind


class Layout:
    """Where every field of the elements of one structure lies (body offsets, in element order)."""

    def __init__(self, records: bool = True):
        self.records = records                 # whether elements may be laid out as records (_scan_fixed)
        self.blocks: dict[int, list] = {}      # id(block) -> [block, starts]
        self.strings: dict[str, list] = {}     # name -> offsets of the length words
        self.lengths: dict[str, list] = {}     # name -> lengths (NUL included)
        self.seqs: dict[str, list] = {}        # name -> [counts, offsets of the counts, Layout | (code, starts)]
        #: (_Struct, element starts, string lengths): every element laid out as one record (_scan_fixed)
        self.fixed = None


class _Refit(Exception):
    """A second run of elements into a Layout laid out as records (_scan_fixed): lay out without records."""


class _Prep:
    """What encoding needs before laying out one structure level: the strings' bytes, the sequences'
    counts and child levels, flat over the level's elements; ``next``: the next element to lay out."""

    def __init__(self, st: _Struct, cols: dict, n: int):
        self.cols, self.next = cols, 0
        self.strs: dict[str, list] = {}
        #: a column of ASCII strings of one length as bytes (n, length + 1), the NUL last (cols[name] a numpy
        #: str array: one cast instead of a bytes object per string); its strs made when asked (strings)
        self.chars: dict[str, np.ndarray] = {}
        self.counts: dict[str, np.ndarray] = {}
        self.child: dict[str, object] = {}
        for step in st.steps:
            if step[0] == "str":
                v = cols[step[1]]
                if isinstance(v, np.ndarray) and v.dtype.kind == "U" and v.ndim == 1 and len(v) == n > 1:
                    chars = _ascii_chars(v)
                    if chars is not None:
                        self.chars[step[1]] = chars
                        continue
                v = [v] if isinstance(v, str) else (v.tolist() if isinstance(v, np.ndarray) else v)
                b = [str(x).encode("utf-8") + b"\x00" for x in v]
                if len(b) != n:
                    raise ValueError(f"column {step[1]}: {len(b)} strings for {n} elements")
                self.strs[step[1]] = b
            elif step[0] == "seq":
                name, elem = step[1], step[2]
                v = cols[name]
                counts, values = v if isinstance(v, tuple) else ([len(v)], v)
                counts = np.atleast_1d(np.asarray(counts, dtype=np.int64))
                if len(counts) != n:
                    raise ValueError(f"sequence {name}: {len(counts)} counts for {n} elements")
                self.counts[name] = counts
                self.child[name] = _Prep(elem, values, int(counts.sum())) if isinstance(elem, _Struct) else values


    def strings(self, name: str) -> list:
        """The bytes of each string of column ``name``, NUL included."""
        got = self.strs.get(name)
        if got is None:
            got = self.strs[name] = [row.tobytes() for row in self.chars[name]]
        return got


#: _ascii_chars by the array's type and bytes (a receiver's satellites and signals change rarely between epochs)
_CHARS_CACHE = BoundedCache(64)


def _ascii_chars(v: np.ndarray):
    """(n, length + 1) bytes of a numpy str array whose strings are ASCII, of one length and without a trailing
    NUL character, the NUL appended (read-only, remembered); None otherwise."""
    key = (v.dtype.str, v.shape, v.tobytes())
    hit = _CHARS_CACHE.get(key)
    if hit is not None:
        return hit[0]
    size = v.dtype.itemsize // 4                 # numpy str: UCS-4 code points, NULs after a shorter string
    codes = np.ascontiguousarray(v).view(np.uint32).reshape(len(v), size)
    if size and (not codes[:, size - 1].all() or codes.max() > 127):   # not one length, or not ASCII
        chars = None
    else:
        chars = np.zeros((len(v), size + 1), dtype=np.uint8)
        chars[:, :size] = codes
        chars.setflags(write=False)
    _CHARS_CACHE.put(key, (chars,))
    return chars


# ------------------------------------------------------------------ scan
def _scan(st: _Struct, n: int, pos: int, lay: Layout, src) -> int:
    """Lay out ``n`` elements of ``st`` from body offset ``pos``; lengths and counts read from ``src``
    (bytes: decoding) or taken from it (_Prep: encoding). Returns the end offset."""
    i0 = 0
    if isinstance(src, _Prep):
        i0, src.next = src.next, src.next + n
    if lay.fixed is not None:
        raise _Refit
    if n > 2 and i0 == 0 and lay.records and not (lay.blocks or lay.strings or lay.seqs):
        end = _scan_fixed(st, n, pos, lay, src)
        if end is not None:
            return end
    if st.flat and n > 2:
        end = _scan_flat(st, n, pos, lay, src, i0)
        if end is not None:
            return end
    return _scan_each(st, n, pos, lay, src, i0)


def _scan_fixed(st: _Struct, n: int, pos: int, lay: Layout, src):
    """_scan of elements whose strings have one length in every element and whose sequences are all empty (the
    satellites of a message, their reflections none): the element's layout repeats with its start offset modulo
    8, so each element is one numpy record (_Struct.fixed_template) and the whole sequence a few record arrays.
    None when the elements are not all alike (then _scan_flat or _scan_each lay them out)."""
    strs = [step[1] for step in st.steps if step[0] == "str"]
    seqs = [step[1] for step in st.steps if step[0] == "seq"]
    if isinstance(src, _Prep):
        lengths = []
        for name in strs:
            if name in src.chars:
                lengths.append(src.chars[name].shape[1])
                continue
            got = set(map(len, src.strs[name][:n]))
            if len(got) != 1:
                return None
            lengths.append(got.pop())
        if any(np.any(src.counts[name][:n]) for name in seqs):
            return None
    else:
        lengths, p = [], pos
        for step in st.steps:                    # the first element's string lengths and sequence counts
            if step[0] == "block":
                p += step[1].sizes[p & 7]
                continue
            p = (p + 3) & -4
            if p + 4 > len(src):
                raise CdrError("message shorter than its contents")
            value = _U32.unpack_from(src, p)[0]
            if step[0] == "seq" and value or step[0] == "str" and not value:
                return None
            if step[0] == "str":
                lengths.append(value)
                p += value
            p += 4
    sizes, _, dtypes = st.fixed_template(tuple(lengths))
    # runs of elements with one start offset modulo 8: one element size, back to back (the first element's
    # residue may differ from the others', which then repeat)
    runs = []                       # [residue, first element, end element, byte offset of the first]
    p = pos
    for i in range(n):
        r = p & 7
        if runs and runs[-1][0] == r:
            runs[-1][2] = i + 1
        else:
            runs.append([r, i, i + 1, p])
        p += sizes[r]
    if not isinstance(src, _Prep):
        if p > len(src):
            raise CdrError("message shorter than its contents")
        arr = np.frombuffer(src, np.uint8)
        for r, i0, i1, b0 in runs:
            rec = arr[b0:b0 + (i1 - i0) * sizes[r]].view(dtypes[r])
            k = 0
            for step in st.steps:
                if step[0] == "block":
                    continue
                want = lengths[k] if step[0] == "str" else 0
                k += step[0] == "str"
                if np.any(rec[step[1] + ("#len" if step[0] == "str" else "#count")] != want):
                    return None
    lay.fixed = (st, runs, tuple(lengths), n)
    return p


def _scan_flat(st: _Struct, n: int, pos: int, lay: Layout, src, i0: int):
    """_scan of a structure without sequences whose strings have one length in every element (sv "G05"):
    the layout repeats with the start offset modulo 8, so it is computed once per residue. None when the
    strings differ in length (then each element is laid out in turn)."""
    names = [step[1] for step in st.steps if step[0] == "str"]
    if isinstance(src, _Prep):
        lengths = []
        for name in names:
            b = src.strings(name)
            first = len(b[i0])
            if any(len(x) != first for x in b[i0:i0 + n]):
                return None
            lengths.append(first)
    else:
        first = Layout()
        _scan_each(st, 1, pos, first, src, 0)
        lengths = [first.lengths[name][0] for name in names]
    sizes, offs = st.template(tuple(lengths))
    starts = [0] * n
    p = pos
    for i in range(n):
        starts[i] = p
        p += sizes[p & 7]
    s = np.array(starts, dtype=np.int64)
    at = s[:, None] + offs[s & 7]               # (n, steps)
    if not isinstance(src, _Prep):
        if p > len(src):
            raise CdrError("message shorter than its contents")
        arr = np.frombuffer(src, np.uint8)
        k = 0
        for j, step in enumerate(st.steps):
            if step[0] == "str":
                if np.any(_gather(arr, at[:, j], "u4") != lengths[k]):
                    return None
                k += 1
    k = 0
    for j, step in enumerate(st.steps):
        if step[0] == "block":
            lay.blocks.setdefault(id(step[1]), [step[1], []])[1].extend(at[:, j].tolist())
        else:
            lay.strings.setdefault(step[1], []).extend(at[:, j].tolist())
            lay.lengths.setdefault(step[1], []).extend([lengths[k]] * n)
            k += 1
    return p


def _scan_each(st: _Struct, n: int, pos: int, lay: Layout, src, i0: int) -> int:
    """_scan element by element (strings of any length, nested sequences)."""
    reading = not isinstance(src, _Prep)
    size = len(src) if reading else 0
    steps = []
    for step in st.steps:
        if step[0] == "block":
            steps.append((0, step[1], lay.blocks.setdefault(id(step[1]), [step[1], []])[1], None))
        elif step[0] == "str":
            steps.append((1, None if reading else src.strings(step[1]), lay.strings.setdefault(step[1], []),
                          lay.lengths.setdefault(step[1], [])))
        else:
            name, elem = step[1], step[2]
            sub = lay.seqs.get(name)
            if sub is None:
                sub = lay.seqs[name] = [[], [], Layout(lay.records) if isinstance(elem, _Struct) else (elem, [])]
            steps.append((2, elem, sub, None if reading else (src.counts[name], src.child[name])))
    for i in range(i0, i0 + n):
        for kind, a, out, extra in steps:
            if kind == 0:
                out.append(pos)
                pos += a.sizes[pos & 7]
                continue
            pos = (pos + 3) & -4
            if reading:
                if pos + 4 > size:
                    raise CdrError("message shorter than its contents")
                value = _U32.unpack_from(src, pos)[0]
            if kind == 1:
                length = value if reading else len(a[i])
                out.append(pos)
                extra.append(length)
                pos += 4 + length
            else:
                count = value if reading else int(extra[0][i])
                out[0].append(count)
                out[1].append(pos)
                pos += 4
                if not count:
                    continue
                if isinstance(a, str):
                    pos = _align(pos, _SIZES[a])
                    out[2][1].append(pos)
                    pos += count * _SIZES[a]
                elif a.uniform is not None:
                    b = a.uniform
                    pos = _align(pos, b.align)
                    out[2].blocks.setdefault(id(b), [b, []])[1].extend(range(pos, pos + count * b.sizes[0], b.sizes[0]))
                    pos += count * b.sizes[0]
                else:
                    pos = _scan(a, count, pos, out[2], src if reading else extra[1])
        if reading and pos > size:
            raise CdrError("message shorter than its contents")
    return pos


# ------------------------------------------------------------------ decode
def _offsets(block: _Block, starts) -> np.ndarray:
    s = np.asarray(starts, dtype=np.int64)
    return s[:, None] + block.offsets[s & 7]           # (n, fields)


def _dtype(code: str) -> str:
    return "?" if code == "b1" else "<" + code


def _gather(arr: np.ndarray, off: np.ndarray, code: str) -> np.ndarray:
    size = _SIZES[code]
    raw = arr[off[:, None] + np.arange(size)] if size > 1 else arr[off]
    return raw.reshape(-1).view(_dtype(code))


def _strings(body: bytes, arr: np.ndarray, offsets: list, lengths: list) -> np.ndarray:
    if not offsets:
        return np.zeros(0, dtype="<U1")
    if min(lengths) == 0:
        raise CdrError("string without its NUL")
    first = lengths[0]
    if lengths.count(first) == len(lengths):            # one length (sv "G05", code "1C"): one gather
        off = np.asarray(offsets, dtype=np.int64) + 4
        return _chars_to_strings(arr[off[:, None] + np.arange(first)], first)
    out = []
    for p, length in zip(offsets, lengths):
        if body[p + 3 + length] != 0:
            raise CdrError("string without its NUL")
        try:
            out.append(body[p + 4:p + 3 + length].decode("utf-8"))
        except UnicodeDecodeError as exc:
            raise CdrError(f"string not UTF-8: {exc}") from None
    return np.array(out)


def _chars_to_strings(chars: np.ndarray, length: int) -> np.ndarray:
    """Strings of one ``length`` (NUL included) from their bytes (n, length)."""
    if chars[:, -1].any():
        raise CdrError("string without its NUL")
    if length == 1:
        return np.full(len(chars), "", dtype="<U1")
    raw = chars[:, :-1].copy().view(f"S{length - 1}").ravel()
    try:
        return raw.astype(f"<U{length - 1}")       # ASCII (satellite ids, signal codes): one cast
    except UnicodeDecodeError:
        try:
            return np.char.decode(raw, "utf-8")
        except UnicodeDecodeError as exc:
            raise CdrError(f"string not UTF-8: {exc}") from None


def _seq_offsets(counts: np.ndarray, starts, size: int) -> np.ndarray:
    """Offsets of every element of sequences of primitives (one start per non-empty sequence)."""
    c = counts[counts > 0]
    if not len(c):
        return np.zeros(0, dtype=np.int64)
    first = np.repeat(np.asarray(starts, dtype=np.int64), c)
    return first + size * (np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c))


def _residue_groups(starts):
    """(starts array, [(residue, element indices or None for all)]) of blocks starting at ``starts``."""
    s = np.asarray(starts, dtype=np.int64)
    r = s & 7
    if not len(s) or np.all(r == r[0]):
        return s, [(int(r[0]) if len(s) else 0, None)]
    return s, [(int(q), np.flatnonzero(r == q)) for q in np.unique(r)]


def _records(lay: Layout, arr: np.ndarray) -> list:
    """The record arrays (views of ``arr``) of a Layout laid out as records, one per run (_scan_fixed)."""
    st, runs, lengths, _ = lay.fixed
    sizes, _, dtypes = st.fixed_template(lengths)
    return [arr[b0:b0 + (i1 - i0) * sizes[r]].view(dtypes[r]) for r, i0, i1, b0 in runs]


def _record_columns(lay: Layout, arr: np.ndarray) -> dict:
    """_columns of a Layout laid out as records (_scan_fixed)."""
    st, _, lengths, n = lay.fixed
    recs = _records(lay, arr)

    def column(name):
        return recs[0][name].copy() if len(recs) == 1 else np.concatenate([rec[name] for rec in recs])

    out: dict = {}
    k = 0
    for step in st.steps:
        if step[0] == "block":
            for name in step[1].names:
                out[name] = column(name)
        elif step[0] == "str":
            out[step[1]] = _chars_to_strings(column(step[1]), lengths[k])
            k += 1
        else:
            elem = step[2]
            out[step[1]] = (np.zeros(n, dtype=np.int64), {} if isinstance(elem, _Struct) else
                            np.zeros(0, dtype=_dtype(elem)))
    return out


def _columns(lay: Layout, body: bytes, arr: np.ndarray) -> dict:
    if lay.fixed is not None:
        return _record_columns(lay, arr)
    out: dict = {}
    for block, starts in lay.blocks.values():
        s, groups = _residue_groups(starts)
        if len(groups) > 1:
            for name, code in zip(block.names, block.codes):
                out[name] = np.empty(len(s), dtype=_dtype(code))
        for r, idx in groups:
            at = s if idx is None else s[idx]
            rec = arr[at[:, None] + np.arange(block.sizes[r])].view(block.dtypes[r]).reshape(-1)
            for name in block.names:
                if idx is None:
                    out[name] = rec[name].copy()
                else:
                    out[name][idx] = rec[name]
    for name, offsets in lay.strings.items():
        out[name] = _strings(body, arr, offsets, lay.lengths[name])
    for name, (counts, _, sub) in lay.seqs.items():
        counts = np.asarray(counts, dtype=np.int64)
        if isinstance(sub, Layout):
            out[name] = (counts, _columns(sub, body, arr))
        else:
            out[name] = (counts, _gather(arr, _seq_offsets(counts, sub[1], _SIZES[sub[0]]), sub[0]))
    return out


def _empty_columns(st: _Struct) -> dict:
    """Columns of zero elements (a sequence no element of which was laid out)."""
    out: dict = {}
    for step in st.steps:
        if step[0] == "block":
            out.update({n: np.zeros(0, dtype=_dtype(c)) for n, c in zip(step[1].names, step[1].codes)})
        elif step[0] == "str":
            out[step[1]] = np.zeros(0, dtype="<U1")
        else:
            elem = step[2]
            out[step[1]] = (np.zeros(0, dtype=np.int64),
                            _empty_columns(elem) if isinstance(elem, _Struct) else np.zeros(0, dtype=_dtype(elem)))
    return out


def _complete(st: _Struct, cols: dict) -> dict:
    """Every field of ``st`` in ``cols`` (empty columns for what no element held)."""
    for step in st.steps:
        if step[0] == "block":
            for n, c in zip(step[1].names, step[1].codes):
                cols.setdefault(n, np.zeros(0, dtype=_dtype(c)))
        elif step[0] == "str":
            cols.setdefault(step[1], np.zeros(0, dtype="<U1"))
        elif isinstance(step[2], _Struct):
            counts, sub = cols[step[1]]
            cols[step[1]] = (counts, _complete(step[2], sub) if sub else _empty_columns(step[2]))
    return cols


# ------------------------------------------------------------------ encode
def _scatter(body: np.ndarray, off: np.ndarray, values, code: str):
    values = np.ascontiguousarray(np.asarray(values).reshape(-1), dtype=_dtype(code))
    if len(off) != len(values):
        raise ValueError(f"{len(values)} values for {len(off)} places")
    size = _SIZES[code]
    raw = values.view(np.uint8)
    if size == 1:
        body[off] = raw
    else:
        body[off[:, None] + np.arange(size)] = raw.reshape(-1, size)


def _write_records(lay: Layout, prep: _Prep, body: np.ndarray):
    """_write of a Layout laid out as records (_scan_fixed): each run's elements written as one record array
    into ``body`` (its padding already the pad value)."""
    st, runs, lengths, n = lay.fixed
    values, k = {}, 0
    for step in st.steps:
        if step[0] == "block":
            for name in step[1].names:
                v = values[name] = np.asarray(prep.cols[name]).reshape(-1)
                if len(v) != n:
                    raise ValueError(f"column {name}: {len(v)} values for {n} elements")
        elif step[0] == "str":
            values[step[1] + "#len"] = lengths[k]
            chars = prep.chars.get(step[1])
            values[step[1]] = chars if chars is not None else np.frombuffer(
                b"".join(prep.strs[step[1]][:n]), np.uint8).reshape(n, lengths[k])
            k += 1
        else:
            values[step[1] + "#count"] = 0
    for (_, i0, i1, _), rec in zip(runs, _records(lay, body)):
        whole = i0 == 0 and i1 == n
        for name, v in values.items():
            rec[name] = v if whole or np.ndim(v) == 0 else v[i0:i1]


def _write(lay: Layout, prep: _Prep, body: np.ndarray, pad: int):
    if lay.fixed is not None:
        return _write_records(lay, prep, body)
    cols = prep.cols
    for block, starts in lay.blocks.values():
        if not starts:
            continue
        s, groups = _residue_groups(starts)
        values = {name: np.asarray(cols[name]).reshape(-1) for name in block.names}
        for name, v in values.items():
            if len(v) != len(s):
                raise ValueError(f"column {name}: {len(v)} values for {len(s)} elements")
        for r, idx in groups:
            at = s if idx is None else s[idx]
            rec = np.empty(len(at), dtype=block.dtypes[r])
            raw = rec.view(np.uint8).reshape(len(at), block.sizes[r])
            raw[:] = pad             # the padding inside the block
            for name, v in values.items():
                rec[name] = v if idx is None else v[idx]
            body[at[:, None] + np.arange(block.sizes[r])] = raw
    for name, offsets in lay.strings.items():
        _scatter(body, np.asarray(offsets, dtype=np.int64), lay.lengths[name], "u4")
        strs = prep.strings(name)
        lengths = lay.lengths[name]
        if lengths and lengths.count(lengths[0]) == len(lengths):      # one length: one scatter
            chars = np.frombuffer(b"".join(strs), np.uint8).reshape(len(strs), lengths[0])
            body[np.asarray(offsets, dtype=np.int64)[:, None] + 4 + np.arange(lengths[0])] = chars
        else:
            for p, b in zip(offsets, strs):
                body[p + 4:p + 4 + len(b)] = np.frombuffer(b, np.uint8)
    for name, (counts, count_pos, sub) in lay.seqs.items():
        _scatter(body, np.asarray(count_pos, dtype=np.int64), counts, "u4")
        child = prep.child[name]
        if isinstance(sub, Layout):
            _write(sub, child, body, pad)
        elif sub[1]:
            _scatter(body, _seq_offsets(np.asarray(counts, dtype=np.int64), sub[1], _SIZES[sub[0]]), child, sub[0])


class Codec:
    """One message type: ``decode(bytes) -> columns``, ``encode(columns) -> bytes``.

    Columns: {field: array over the elements} (the top level: arrays of one element; nested
    structures as "name.field"); a sequence: {name: (counts, columns)}, counts the elements of each
    parent element and columns flat over all of them (a sequence of primitives: (counts, values)).
    ``encode`` also takes scalars, strings and, for a top-level sequence, its columns alone."""

    def __init__(self, schema):
        self.schema = schema
        self.root = _Struct(schema)
        self._top_seq_names = {s[1] for s in self.root.steps if s[0] == "seq" and isinstance(s[2], _Struct)}
        #: (name, element _Struct) of a message whose one sequence is its last field, of flat elements
        #: (_encode_records), else None
        seqs = [s for s in self.root.steps if s[0] == "seq"]
        last = self.root.steps[-1]
        self._tail = ((last[1], last[2]) if len(seqs) == 1 and last[0] == "seq" and isinstance(last[2], _Struct)
                      and last[2].flat else None)

    def decode(self, data) -> dict:
        data = bytes(data)
        if len(data) < 4 or data[:2] != HEADER_LE[:2]:
            raise CdrError(f"not little-endian CDR (encapsulation {data[:4].hex()})")
        body = data[4:]
        try:
            lay = Layout()
            _scan(self.root, 1, 0, lay, body)
        except _Refit:
            lay = Layout(records=False)
            _scan(self.root, 1, 0, lay, body)
        return _complete(self.root, _columns(lay, body, np.frombuffer(body, np.uint8)))

    def encode(self, cols: dict, pad: int = 0) -> bytes:
        """``pad``: the value of the padding bytes (the tests tell padding from data by encoding twice)."""
        cols = {k: (v if isinstance(v, tuple) or k not in self._top_seqs else ([len(_first(v))], v))
                for k, v in cols.items()}
        fast = self._encode_records(cols, pad)
        if fast is not None:
            return fast
        try:
            prep, lay = _Prep(self.root, cols, 1), Layout()
            end = _scan(self.root, 1, 0, lay, prep)
        except _Refit:
            prep, lay = _Prep(self.root, cols, 1), Layout(records=False)
            end = _scan(self.root, 1, 0, lay, prep)
        body = np.full(_align(end, 4), pad, dtype=np.uint8)
        _write(lay, prep, body, pad)
        return HEADER_LE + body.tobytes()

    @property
    def _top_seqs(self):
        return self._top_seq_names

    def _encode_records(self, cols: dict, pad: int):
        """encode's bytes laid out as records without a Layout, for a message whose one sequence is its last field
        and holds flat elements (no sequence inside) whose string columns are numpy ASCII strings of one length
        (Observations: the header and epoch fields, then the signals): the message's fields up to the count as
        one record (_Struct.fixed_template of the root, its sequence empty), the elements as _scan_fixed lays them
        out (runs of one start offset modulo 8, each a record array); the same bytes as the general path.  None
        when the message or the columns are not of that kind (the general path encodes them)."""
        tail = self._tail
        if tail is None:
            return None
        name, elem = tail
        seq = cols.get(name)
        if not isinstance(seq, tuple):
            return None
        counts, values = seq
        counts = np.atleast_1d(np.asarray(counts, dtype=np.int64))
        n = int(counts[0]) if len(counts) == 1 else -1
        if n <= 2 or not isinstance(values, dict):
            return None
        chars, lengths = {}, []
        for step in elem.steps:
            if step[0] == "str":
                v = values.get(step[1])
                c = _ascii_chars(v) if isinstance(v, np.ndarray) and v.dtype.kind == "U" and v.shape == (n,) else None
                if c is None:
                    return None
                chars[step[1]] = c
                lengths.append(c.shape[1])
        head, head_lengths = {}, []
        for step in self.root.steps:
            if step[0] == "str":
                v = cols[step[1]]
                if isinstance(v, np.ndarray):
                    v = v.reshape(-1)[0] if v.size == 1 else None
                if not isinstance(v, str):
                    return None
                b = v.encode("utf-8") + b"\x00"
                head[step[1]] = np.frombuffer(b, np.uint8)
                head[step[1] + "#len"] = len(b)
                head_lengths.append(len(b))
        head[name + "#count"] = n
        root_sizes, _, root_dtypes = self.root.fixed_template(tuple(head_lengths))
        sizes, _, dtypes = elem.fixed_template(tuple(lengths))
        runs, p = [], root_sizes[0]          # [residue, first element, end element, byte offset of the first]
        i = 0
        while i < n:
            r = p & 7
            if (p + sizes[r]) & 7 == r:      # the residue repeats from here: one run of the rest
                runs.append((r, i, n, p))
                p += (n - i) * sizes[r]
                break
            runs.append((r, i, i + 1, p))
            p += sizes[r]
            i += 1
        body = np.full(_align(p, 4), pad, dtype=np.uint8)
        rec = body[:root_sizes[0]].view(root_dtypes[0])
        for field_name in root_dtypes[0].names:
            v = head.get(field_name)
            if v is None:
                v = np.asarray(cols[field_name]).reshape(-1)
                if len(v) != 1:
                    raise ValueError(f"column {field_name}: {len(v)} values for 1 elements")
            rec[field_name] = v
        element = {}
        for step in elem.steps:
            if step[0] == "block":
                for field_name in step[1].names:
                    v = element[field_name] = np.asarray(values[field_name]).reshape(-1)
                    if len(v) != n:
                        raise ValueError(f"column {field_name}: {len(v)} values for {n} elements")
            else:
                element[step[1] + "#len"] = chars[step[1]].shape[1]
                element[step[1]] = chars[step[1]]
        for r, i0, i1, b0 in runs:
            rec = body[b0:b0 + (i1 - i0) * sizes[r]].view(dtypes[r])
            whole = i0 == 0 and i1 == n
            for field_name, v in element.items():
                rec[field_name] = v if whole or np.ndim(v) == 0 else v[i0:i1]
        return HEADER_LE + body.tobytes()


def _first(cols):
    """Number of elements of a columns dict (its first column's length)."""
    if not isinstance(cols, dict):
        return cols
    for v in cols.values():
        return v[0] if isinstance(v, tuple) else v
    return []


# ------------------------------------------------------------------ gnss_sim_msgs (msg_pkg/msg/*.msg)
SATELLITE_STATE = (
    ("sv", "str"), ("system", "u1"), ("prn", "u2"), ("glonass_channel", "i1"), ("position_ecef_m", XYZ),
    ("velocity_ecef_mps", XYZ), ("acceleration_ecef_mps2", XYZ), ("clock_bias_s", "f8"), ("clock_drift_sps", "f8"),
    ("relativistic_correction_s", "f8"), ("group_delay_s", "f8"), ("health", "u2"), ("issue_of_data", "i4"),
    ("ephemeris_age_s", "f8"), ("orbit_source", "u1"))
SATELLITE_STATES = (
    ("header", HEADER), ("gps_week", "u4"), ("gps_tow_s", "f8"), ("states", ("seq", SATELLITE_STATE)),
    ("klobuchar_alpha", ("seq", "f8")), ("klobuchar_beta", ("seq", "f8")), ("nequick_coefficients", ("seq", "f8")))
REFLECTED_PATH = (
    ("excess_path_m", "f8"), ("gamma_co_re", "f8"), ("gamma_co_im", "f8"), ("gamma_cross_re", "f8"),
    ("gamma_cross_im", "f8"), ("arrival_elevation_deg", "f8"))
SATELLITE_VISIBILITY = (
    ("sv", "str"), ("azimuth_deg", "f8"), ("elevation_deg", "f8"), ("state", "u1"), ("attenuation_db", "f8"),
    ("extra_path_m", "f8"), ("fraction_blocked", "f4"), ("reflections", ("seq", REFLECTED_PATH)))
VISIBILITY = (
    ("header", HEADER), ("antenna_world_m", XYZ), ("antenna_ecef_m", XYZ),
    ("satellites", ("seq", SATELLITE_VISIBILITY)))
SIGNAL_OBSERVATION = (
    ("sv", "str"), ("code", "str"), ("frequency_hz", "f8"), ("pseudorange_m", "f8"), ("carrier_phase_cycles", "f8"),
    ("doppler_hz", "f8"), ("cn0_dbhz", "f8"), ("lock_time_s", "f8"), ("lli", "u1"), ("loss_of_lock", "b1"),
    ("half_cycle_ambiguity", "b1"))
OBSERVATIONS = (
    ("header", HEADER), ("gps_week", "u4"), ("gps_tow_s", "f8"), ("receiver_clock_offset_s", "f8"),
    ("observations", ("seq", SIGNAL_OBSERVATION)))

STATES_CODEC = Codec(SATELLITE_STATES)
VISIBILITY_CODEC = Codec(VISIBILITY)
OBSERVATIONS_CODEC = Codec(OBSERVATIONS)
