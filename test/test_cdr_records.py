"""The CDR codec's record layout (messages/cdr.py _scan_fixed: a sequence of like elements as numpy records) gives
the bytes and columns of its element-by-element layout, for the messages gnss_sim sends and for the cases that
leave it (strings of other lengths, non-empty nested sequences, nested sequences under a parent laid out element
by element). test_cdr_codec checks the codec's bytes against rclpy's."""
from __future__ import annotations

import numpy as np
import pytest

from gnss_sim_ros2.messages import cdr

INNER = (("name", "str"), ("v", "f8"), ("k", "u1"))
OUTER = (("header", cdr.HEADER), ("items", ("seq", (("tag", "str"), ("w", "f4"), ("inner", ("seq", INNER)),
                                                    ("xs", ("seq", "f8"))))))


def _element_by_element(monkeypatch):
    monkeypatch.setattr(cdr, "_scan_fixed", lambda *a, **k: None)
    monkeypatch.setattr(cdr.Codec, "_encode_records", lambda *a, **k: None)


def _columns_equal(a, b, where="") -> None:
    assert set(a) == set(b), where
    for name in a:
        x, y = a[name], b[name]
        if isinstance(x, tuple):
            np.testing.assert_array_equal(x[0], y[0], err_msg=f"{where}{name} counts")
            if isinstance(x[1], dict):
                _columns_equal(x[1], y[1], f"{where}{name}.")
            else:
                assert x[1].dtype == y[1].dtype, f"{where}{name}"
                np.testing.assert_array_equal(x[1], y[1], err_msg=f"{where}{name}")
        else:
            assert x.dtype == y.dtype and x.shape == y.shape, f"{where}{name}: {x.dtype} {y.dtype}"
            np.testing.assert_array_equal(x, y, err_msg=f"{where}{name}")


def _cases(rng):
    n = 37
    sv = np.array([f"{'GREC'[i % 4]}{i + 1:02d}" for i in range(n)])
    sats = {"sv": sv, "azimuth_deg": rng.uniform(0, 360, n), "elevation_deg": rng.uniform(0, 90, n),
            "state": rng.integers(0, 4, n), "attenuation_db": rng.uniform(0, 20, n),
            "extra_path_m": rng.uniform(0, 30, n), "fraction_blocked": rng.uniform(0, 1, n).astype(np.float32),
            "reflections": (np.zeros(n, dtype=np.int64), {k: np.zeros(0) for k, _ in cdr.REFLECTED_PATH})}
    head = {"header.stamp.sec": 7, "header.stamp.nanosec": 5}
    vis = {**head, **{f"antenna_{w}_m.{a}": 1.5 for w in ("world", "ecef") for a in "xyz"}}
    out = []
    for frame in ("w", "world", "robot12/base"):       # the sequence starts at every residue modulo 8
        out.append((cdr.VISIBILITY_CODEC, {**vis, "header.frame_id": frame, "satellites": ([n], sats)}))
    with_refl = dict(sats, reflections=(np.r_[0, 2, np.zeros(n - 2, dtype=np.int64)],
                                        {k: rng.normal(size=2) for k, _ in cdr.REFLECTED_PATH}))
    out.append((cdr.VISIBILITY_CODEC, {**vis, "header.frame_id": "w", "satellites": ([n], with_refl)}))
    odd = dict(sats, sv=np.array(list(sv[:-1]) + ["G7"]))              # the last string shorter
    out.append((cdr.VISIBILITY_CODEC, {**vis, "header.frame_id": "w", "satellites": ([n], odd)}))
    wide = dict(sats, sv=np.array(["Gä1"] * n))                       # not ASCII: bytes per string
    out.append((cdr.VISIBILITY_CODEC, {**vis, "header.frame_id": "w", "satellites": ([n], wide)}))
    m = 11
    obs = {"sv": np.repeat(sv[:4], 3)[:m], "code": np.array(["1C", "5Q", "7Q"] * 4)[:m]}
    obs.update({k: rng.normal(size=m) for k in ("frequency_hz", "pseudorange_m", "carrier_phase_cycles",
                                                "doppler_hz", "cn0_dbhz", "lock_time_s")})
    obs.update(lli=rng.integers(0, 4, m), loss_of_lock=rng.integers(0, 2, m).astype(bool),
               half_cycle_ambiguity=rng.integers(0, 2, m).astype(bool))
    for frame in ("", "ant", "robot0/antenna"):
        out.append((cdr.OBSERVATIONS_CODEC, {**head, "header.frame_id": frame, "gps_week": 2369, "gps_tow_s": 1.5,
                                             "receiver_clock_offset_s": 1e-4, "observations": ([m], obs)}))
    # nested sequences of strings: each item's inner elements alike, so the first item's would go as records and
    # the second item's into the same layout (the codec then lays the message out element by element)
    inner = {"name": np.array(["ab", "cd", "ef", "gh", "ij", "kl"]), "v": rng.normal(size=6),
             "k": np.arange(6)}
    items = {"tag": ["x", "yy", "zzz"], "w": rng.normal(size=3).astype(np.float32),
             "inner": (np.array([3, 3, 0]), inner), "xs": (np.array([0, 2, 1]), rng.normal(size=3))}
    out.append((cdr.Codec(OUTER), {**head, "header.frame_id": "f", "items": ([3], items)}))
    items4 = {"tag": ["ab", "cd", "ef", "gh"], "w": rng.normal(size=4).astype(np.float32),
              "inner": (np.zeros(4, dtype=np.int64), {k: v[:0] for k, v in inner.items()}),
              "xs": (np.zeros(4, dtype=np.int64), np.zeros(0))}
    out.append((cdr.Codec(OUTER), {**head, "header.frame_id": "f", "items": ([4], items4)}))
    return out


#: the cases whose sequence goes as records (the others: unlike elements, element by element); case 9 starts as
#: records and is laid out again element by element (_Refit)
AS_RECORDS = {0, 1, 2, 5, 6, 7, 8, 9, 10}


@pytest.mark.parametrize("case", range(11))
def test_records_give_the_element_by_element_bytes_and_columns(case, monkeypatch):
    codec, cols = _cases(np.random.default_rng(case))[case]
    used = []
    real = cdr._scan_fixed

    def spy(*a, **k):
        end = real(*a, **k)
        used.append(end is not None)
        return end

    with monkeypatch.context() as m:
        m.setattr(cdr, "_scan_fixed", spy)
        fast = codec.encode(cols)
        fast_pad = codec.encode(cols, pad=0xFF)
        fast_cols = codec.decode(fast)
    assert any(used) == (case in AS_RECORDS), used
    with monkeypatch.context() as m:
        _element_by_element(m)
        slow = codec.encode(cols)
        slow_pad = codec.encode(cols, pad=0xFF)
        slow_cols = codec.decode(slow)
    assert fast == slow and fast_pad == slow_pad
    _columns_equal(fast_cols, slow_cols)


def _decoded(codec, data):
    try:
        return codec.decode(data)
    except cdr.CdrError as exc:
        return str(exc)


@pytest.mark.parametrize("length", [0, 3, 5, 9, 2 ** 31])
def test_broken_and_unlike_elements_read_as_element_by_element(length, monkeypatch):
    """Bytes whose middle element's string length word differs (or a truncated message): what the element-by-element
    reading makes of them, the same error or the same columns."""
    codec, cols = _cases(np.random.default_rng(1))[0]
    data = codec.encode(cols)
    bad = bytearray(data)
    at = data.index(b"E11\x00") - 4
    bad[at:at + 4] = length.to_bytes(4, "little")
    for raw in (bytes(bad), data[:-40]):
        fast = _decoded(codec, raw)
        with monkeypatch.context() as m:
            _element_by_element(m)
            slow = _decoded(codec, raw)
        if isinstance(slow, str):
            assert fast == slow
        else:
            _columns_equal(fast, slow)
    assert "shorter" in _decoded(codec, data[:-40])


@pytest.mark.parametrize("n", [3, 4, 11])
def test_observations_encoded_as_records_without_a_layout(n, monkeypatch):
    """Codec._encode_records (a message whose one sequence comes last, of flat elements: Observations) gives the
    general path's bytes, whatever the residue modulo 8 the sequence starts at (frame ids of 0-8 characters) and
    the padding value; it leaves to the general path what it does not lay out (unlike strings, not ASCII, n <= 2)."""
    rng = np.random.default_rng(n)
    obs = {"sv": np.array([f"{'GRE'[i % 3]}{i + 1:02d}" for i in range(n)]),
           "code": np.array(["1C", "5Q", "7Q"] * n)[:n]}
    obs.update({k: rng.normal(size=n) for k in ("frequency_hz", "pseudorange_m", "carrier_phase_cycles",
                                                "doppler_hz", "cn0_dbhz", "lock_time_s")})
    obs.update(lli=rng.integers(0, 4, n), loss_of_lock=rng.integers(0, 2, n).astype(bool),
               half_cycle_ambiguity=rng.integers(0, 2, n).astype(bool))
    codec = cdr.OBSERVATIONS_CODEC
    calls = []
    real = cdr.Codec._encode_records

    def spy(self, cols, pad):
        got = real(self, cols, pad)
        calls.append(got is not None)
        return got

    for frame in ["abcdefgh"[:k] for k in range(9)]:
        cols = {"header.stamp.sec": -3, "header.stamp.nanosec": 7, "header.frame_id": frame, "gps_week": 2369,
                "gps_tow_s": 0.1, "receiver_clock_offset_s": -2e-4, "observations": ([n], obs)}
        with monkeypatch.context() as m:
            m.setattr(cdr.Codec, "_encode_records", spy)
            fast = [codec.encode(cols, pad=pad) for pad in (0, 0xFF)]
        with monkeypatch.context() as m:
            _element_by_element(m)
            slow = [codec.encode(cols, pad=pad) for pad in (0, 0xFF)]
        assert fast == slow, frame
    assert calls and all(calls)
    for other in (dict(obs, sv=np.array(["G1"] + [f"G{i:02d}" for i in range(1, n)])),      # unlike lengths
                  dict(obs, code=np.array(["1ä"] * n))):                                     # not ASCII
        cols = {"header.stamp.sec": 1, "header.stamp.nanosec": 0, "header.frame_id": "a", "gps_week": 1,
                "gps_tow_s": 0.0, "receiver_clock_offset_s": 0.0, "observations": ([n], other)}
        assert real(codec, cols, 0) is None
