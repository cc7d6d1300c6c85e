"""Weave tables: plain, twill a/b, satin, explicit."""
import numpy as np
import pytest

from fraytool.scene import weave


def test_plain_alternates_in_both_directions():
    t = np.array(weave.plain())
    assert (t != np.roll(t, 1, axis=0)).all() and (t != np.roll(t, 1, axis=1)).all()


@pytest.mark.parametrize("ratio,over,under", [("2/1", 2, 1), ("2/2", 2, 2), ("3/1", 3, 1)])
def test_twill_floats_and_diagonal(ratio, over, under):
    t = np.array(weave.twill(ratio))
    n = over + under
    assert t.shape == (n, n)
    for row in t:  # each weft: one run of `over` on top (cyclically), `under` below
        assert row.sum() == over
        assert np.count_nonzero(row != np.roll(row, 1)) == 2
    assert (np.roll(t[0], 1) == t[1]).all()  # the twill line: shifted by one warp per row


def test_satin_has_one_isolated_warp_point_per_row_and_column():
    t = np.array(weave.satin(5))
    assert ((~t).sum(axis=0) == 1).all() and ((~t).sum(axis=1) == 1).all()
    pts = np.argwhere(~t)
    for a in pts:  # no two warp points touch side by side
        for b in pts:
            if (a != b).any():
                d = np.abs(a - b)
                d = np.minimum(d, 5 - d)
                assert not (d.max() == 1 and d.min() == 0)


def test_bad_twill_raises():
    with pytest.raises(ValueError):
        weave.twill("2-1")
