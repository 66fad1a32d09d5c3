"""The link ``virtual-board/tty`` of the per-user cache to a virtual board's pty: one per running board."""

import os

from fliss.host.virtual import claim_link, release_link


def _pty():
    master, slave = os.openpty()
    return master, slave, os.ttyname(slave)


def test_each_board_has_its_own_link(tmp_path):
    first, second, third = _pty(), _pty(), _pty()
    try:
        # Two boards side by side: the second gets tty-2, and each link leads to its own pty.
        link_1 = claim_link(tmp_path, first[2])
        link_2 = claim_link(tmp_path, second[2])
        assert (link_1, link_2) == (tmp_path / "tty", tmp_path / "tty-2")
        assert (os.readlink(link_1), os.readlink(link_2)) == (first[2], second[2])
        # The first one stops: its link goes, the second's stays; a third board takes tty.
        release_link(link_1, first[2])
        assert not link_1.exists() and os.readlink(link_2) == second[2]
        assert claim_link(tmp_path, third[2]) == tmp_path / "tty"
        # A link another board holds is never removed by one that does not own it.
        release_link(link_2, third[2])
        assert os.readlink(link_2) == second[2]
    finally:
        for master, slave, _ in (first, second, third):
            os.close(master)
            os.close(slave)


def test_a_link_left_by_a_board_that_is_gone_is_taken_over(tmp_path):
    (tmp_path / "tty").symlink_to(tmp_path / "no-such-pty")     # a board killed with -9
    master, slave, path = _pty()
    try:
        assert claim_link(tmp_path, path) == tmp_path / "tty"
        assert os.readlink(tmp_path / "tty") == path
    finally:
        os.close(master)
        os.close(slave)
