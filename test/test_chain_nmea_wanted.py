"""ReceiverChain.finish(nmea=False): a receiver node whose NMEA topic has no subscribers (ReceiverSession.wanted)
makes no NMEA text, and everything else of the epoch is what it is with the text: the fix, the RINEX observation
file and fix.csv byte for byte; an NMEA file asked for (write_nmea_file) still gets every epoch's sentences."""
from __future__ import annotations

import pytest
from receiver_helpers import synthetic_sky

EPOCHS = 30


@pytest.fixture(scope="module")
def epochs():
    """(receiver parameters, [(t, antenna ECEF, states)]) at 10 Hz from the synthetic ephemeris, antenna fixed."""
    from gnss_sim_ros2.core.frames import geodetic_to_ecef

    rcv, start, provider = synthetic_sky(10.0, 10.0)
    ecef = geodetic_to_ecef(47.37, 8.54, 450.0)
    return rcv, [(start + 0.1 * i, ecef, provider.states(start + 0.1 * i, systems=rcv["systems"]))
                 for i in range(EPOCHS)]


def _run(rcv, data, out_dir, wanted, nmea_file=False):
    from gnss_sim_ros2.core.receiver.chain import ChainSettings, ReceiverChain

    p = {**rcv, "output_dir": str(out_dir), "write_nmea_file": nmea_file}
    chain = ReceiverChain(ChainSettings.from_params(p), None, nmea=True, comment="test")
    texts, fixes = [], []
    for i, (t, ecef, states) in enumerate(data):
        obs = chain.observe(t, ecef, states)
        ep = chain.finish(t, ecef, states, obs, nmea=wanted(i))
        texts.append(ep.nmea)
        fixes.append((ep.sol.status, ep.sol.pos_ecef_m.tobytes()))
    chain.close()
    files = {f.name: b"".join(line for line in f.read_bytes().splitlines(True) if b"PGM / RUN BY" not in line)
             for f in out_dir.iterdir()}
    return texts, fixes, files


def test_no_nmea_text_when_nobody_listens_the_rest_unchanged(epochs, tmp_path):
    rcv, data = epochs
    every = _run(rcv, data, tmp_path / "every", lambda i: True)
    some = _run(rcv, data, tmp_path / "some", lambda i: i % 3 == 0)     # a subscriber comes and goes
    assert all(t.startswith("$G") for t in every[0])
    assert [t for i, t in enumerate(some[0]) if i % 3] == [""] * (EPOCHS - EPOCHS // 3)
    assert [t for i, t in enumerate(some[0]) if i % 3 == 0] == every[0][::3]
    assert some[1] == every[1] and any(status == "fix" for status, _ in every[1])
    assert some[2] == every[2] and any(name.endswith("_MO.rnx") for name in every[2]) and "fix.csv" in every[2]


def test_an_nmea_file_gets_its_sentences_without_subscribers(epochs, tmp_path):
    rcv, data = epochs
    every = _run(rcv, data, tmp_path / "every", lambda i: True, nmea_file=True)
    none = _run(rcv, data, tmp_path / "none", lambda i: False, nmea_file=True)
    assert none[0] == every[0] and none[2] == every[2]
    assert none[2]["gnss_sim.nmea"].decode("ascii") == "".join(every[0])
