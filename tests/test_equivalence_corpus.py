"""Every env API plays the recorded seeded episodes of every map bit for bit (``tests/equivalence_corpus.py``)."""

import pytest
from equivalence_corpus import APIS, PLAYERS, load

from smac_hard_gym.maps import list_maps

CORPUS = load()


def test_corpus_covers_every_map():
    assert sorted(CORPUS) == sorted(list_maps())


# Three maps cover the mechanics in the fast tier (marines; heals and a medivac; shields, zealots and missiles); the
# other twenty run in the long tier, which CI runs too.
FAST_MAPS = ("3m", "MMM", "2s3z")


@pytest.mark.parametrize("map_name", [m if m in FAST_MAPS else pytest.param(m, marks=pytest.mark.long)
                                      for m in sorted(list_maps())])
def test_replays_bit_for_bit(map_name):
    played = {api: PLAYERS[api](map_name) for api in APIS}
    assert played == CORPUS[map_name]
