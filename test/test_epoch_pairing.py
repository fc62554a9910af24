"""core/receiver/epoch_pairing.EpochPairing: the receiver's states and visibility paired by stamp."""
from gnss_sim_ros2.core.receiver.epoch_pairing import EpochPairing


def test_pairs_in_either_order_and_in_stamp_order():
    p = EpochPairing()
    assert p.add_states((1, 0), "s1") == []
    assert p.add_states((2, 0), "s2") == []
    assert p.add_visibility((2, 0), "v2") == [("s2", "v2")]
    # epoch 1 is now older than the last paired: its states are dropped, its visibility never pairs
    assert p.states == {}
    assert p.add_visibility((1, 0), "v1") == []
    assert p.vis == {}
    assert p.add_visibility((3, 0), "v3") == []
    assert p.add_states((3, 0), "s3") == [("s3", "v3")]
    assert p.last_stamp == (3, 0)


def test_a_repeated_stamp_is_stepped_once():
    p = EpochPairing()
    p.add_states((5, 0), "s")
    assert p.add_visibility((5, 0), "v") == [("s", "v")]
    p.add_states((5, 0), "s again")
    assert p.add_visibility((5, 0), "v again") == []


def test_reset_accepts_older_stamps_again():
    p = EpochPairing()
    p.add_states((5, 0), "s")
    p.add_visibility((5, 0), "v")
    p.add_states((1, 0), "s_old")
    p.clear()
    assert p.last_stamp == (5, 0)
    p.reset()
    p.add_states((1, 0), "s1")
    assert p.add_visibility((1, 0), "v1") == [("s1", "v1")]
