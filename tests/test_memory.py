"""The C heap during a large solve (gdfe._memory): thresholds raised and given back, the same answers."""

import threading

import numpy as np
import pytest

import gdfe
from gdfe import _memory
from studies.bench import H, SHEET_PIXEL, SHEET_R, mask_sheet

MiB = 2**20


class _FakeLibc:
    """Records ``mallopt`` and ``malloc_trim`` calls instead of making them."""

    def __init__(self):
        self.calls = []

    def mallopt(self, param, value):
        self.calls.append((param, value))
        return 1

    def trim(self, pad):
        self.calls.append(("trim", pad))
        return 1

    def thresholds(self):
        """The mmap and trim thresholds as the calls so far leave them."""
        now = {}
        for param, value in self.calls:
            now[param] = value
        return now.get(_memory._M_MMAP_THRESHOLD), now.get(_memory._M_TRIM_THRESHOLD)


@pytest.fixture
def fake(monkeypatch):
    libc = _FakeLibc()
    for name in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES"):  # no choice of the user's here
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(_memory, "_mallopt", lambda: libc.mallopt)
    monkeypatch.setattr(_memory, "_malloc_trim", lambda: libc.trim)
    return libc


def test_small_blocks_leave_the_dynamic_threshold_alone(fake):
    with _memory.heap_blocks(_memory.DYNAMIC_MMAP_MAX) as raised:
        assert raised is False
    assert fake.calls == []


def test_a_large_block_raises_both_thresholds_and_gives_them_back(fake):
    with _memory.heap_blocks(100 * MiB) as raised:
        assert raised is True
        assert fake.thresholds() == (100 * MiB, 200 * MiB)
    assert fake.thresholds() == (32 * MiB, 64 * MiB)
    assert fake.calls[-1] == ("trim", 0)  # the heap's free memory returned at the end


def test_blocks_open_together_hold_the_largest_until_the_last_closes(fake):
    outer = _memory.heap_blocks(100 * MiB)
    inner = _memory.heap_blocks(300 * MiB)
    outer.__enter__()
    inner.__enter__()
    assert fake.thresholds() == (300 * MiB, 600 * MiB)
    outer.__exit__(None, None, None)  # closed first: the other is still open
    assert fake.thresholds() == (300 * MiB, 600 * MiB)
    assert ("trim", 0) not in fake.calls
    inner.__exit__(None, None, None)
    assert fake.thresholds() == (32 * MiB, 64 * MiB)


def test_an_error_inside_still_gives_the_thresholds_back(fake):
    with pytest.raises(KeyError, match="inside"):
        with _memory.heap_blocks(100 * MiB):
            raise KeyError("inside")
    assert fake.thresholds() == (32 * MiB, 64 * MiB)
    assert _memory._held == []


def test_threads_share_the_held_sizes(fake):
    entered, leave = threading.Barrier(3), threading.Event()

    def hold(size):
        with _memory.heap_blocks(size):
            entered.wait()
            leave.wait()

    workers = [threading.Thread(target=hold, args=(s,)) for s in (50 * MiB, 80 * MiB)]
    for w in workers:
        w.start()
    entered.wait()
    assert fake.thresholds() == (80 * MiB, 160 * MiB)
    leave.set()
    for w in workers:
        w.join()
    assert fake.thresholds() == (32 * MiB, 64 * MiB)


def test_the_thresholds_are_at_most_a_c_int(fake):
    """``mallopt`` takes a C ``int``: a larger size is not passed on wrapped round to a small one."""
    with _memory.heap_blocks(3 * 2**30) as raised:
        assert raised is True
        assert fake.thresholds() == (2**31 - 1, 2**31 - 1)


def test_a_c_library_that_refuses_says_so(fake, monkeypatch):
    monkeypatch.setattr(_memory, "_mallopt", lambda: lambda param, value: 0)  # a stub, as some C libraries have
    with _memory.heap_blocks(100 * MiB) as raised:
        assert raised is False
    assert _memory._held == []


@pytest.mark.parametrize("name, value", [("MALLOC_MMAP_THRESHOLD_", "1048576"), ("MALLOC_TRIM_THRESHOLD_", "0"),
                                         ("GLIBC_TUNABLES", "glibc.malloc.check=0:glibc.malloc.mmap_threshold=65536")])
def test_thresholds_the_environment_chose_are_left_alone(fake, monkeypatch, name, value):
    """A threshold set in the process's environment is the user's: not raised, and not set to another value after."""
    monkeypatch.setenv(name, value)
    with _memory.heap_blocks(100 * MiB) as raised:
        assert raised is False
    assert fake.calls == []


def test_other_tunables_do_not_count_as_a_choice(fake, monkeypatch):
    monkeypatch.setenv("GLIBC_TUNABLES", "glibc.malloc.arena_max=1")
    with _memory.heap_blocks(100 * MiB) as raised:
        assert raised is True


def test_without_mallopt_nothing_is_done(monkeypatch):
    monkeypatch.setattr(_memory, "_mallopt", lambda: None)
    with _memory.heap_blocks(100 * MiB) as raised:
        assert raised is False


def test_simulate_asks_for_a_rotation_per_cell_or_vertex(monkeypatch):
    asked = []
    real = _memory.heap_blocks

    def spy(nbytes):
        asked.append(nbytes)
        return real(nbytes)

    monkeypatch.setattr(_memory, "heap_blocks", spy)
    design = gdfe.from_masks(*mask_sheet(400), SHEET_PIXEL, SHEET_R, h=H, nz=1)
    gdfe.simulate(design, contact="off")
    assert asked == [72 * max(design.mesh.n_points, design.n_cells)]


def test_the_heap_threshold_changes_no_result():
    """The same solve, with the threshold raised by the C library (where it has ``mallopt``) and without: the same bits."""
    design = gdfe.from_masks(*mask_sheet(400), SHEET_PIXEL, SHEET_R, h=H, nz=1)
    plain = gdfe.simulate(design, contact="off")
    with _memory.heap_blocks(64 * MiB) as raised:
        heaped = gdfe.simulate(design, contact="off")
    # the C library's own mallopt took both thresholds wherever it has one (glibc here), unless the environment chose
    assert raised is (_memory._mallopt() is not None and not _memory._chosen_by_the_user())
    assert np.array_equal(plain.points, heaped.points)
    assert plain.energy == heaped.energy and plain.iterations == heaped.iterations
