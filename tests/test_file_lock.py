"""The lock between processes on a file, and a lock that leaves no file behind."""

from __future__ import annotations

import tempfile
import threading
import time

import pytest

from delaytrack._file_lock import LOCKS, exclusive
from delaytrack.live._node import _folder_turn

pytestmark = pytest.mark.skipif(not LOCKS, reason="no fcntl (Windows): no lock")


@pytest.mark.parametrize("remove", [False, True])
def test_one_holder_at_a_time(tmp_path, remove):
    """Threads open the lock file each, as processes would (``flock`` is per open file); with
    ``remove`` a waiter wakes on a file that was deleted and must lock the new one."""
    path = str(tmp_path / "turn.lock")
    inside: list[int] = []
    overlaps: list[int] = []
    entries: list[int] = []

    def take_turns(worker: int) -> None:
        for _ in range(40):
            with exclusive(path, remove=remove):
                if inside:
                    overlaps.append(worker)
                inside.append(worker)
                time.sleep(1e-4)
                inside.remove(worker)
                entries.append(worker)

    threads = [threading.Thread(target=take_turns, args=(w,)) for w in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=60.0)
    assert not any(thread.is_alive() for thread in threads)
    assert overlaps == [] and len(entries) == 6 * 40
    assert (tmp_path / "turn.lock").exists() is not remove


def test_a_live_folders_turn_leaves_no_file(tmp_path, monkeypatch):
    temporary = tmp_path / "temporary"
    temporary.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temporary))
    with _folder_turn(str(tmp_path / "session")):
        assert len(list(temporary.iterdir())) == 1  # the lock, while held
    assert list(temporary.iterdir()) == []
