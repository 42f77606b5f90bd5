"""benchmarks/id_errors.py: changes of id on a person classified and the rows they cost, on
constructed rows whose answer is known."""

from __future__ import annotations

import sys

import numpy as np
from conftest import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
import id_errors  # noqa: E402


def _box(x: float) -> list[float]:
    return [x, 0.0, x + 40.0, 100.0]


def _gt(frames: range, people: dict[int, float]) -> dict:
    ids = np.array(sorted(people), np.int64)
    boxes = np.array([_box(people[i]) for i in ids], np.float64)
    return {f: (ids, boxes, np.ones(len(ids))) for f in frames}


def _rows(spec: list[tuple[int, int, float, int]]) -> np.ndarray:
    """Rows from (frame, id, box x, detection index or -1)."""
    return np.array([[f, i, *_box(x), j] for f, i, x, j in spec], np.float64)


def test_new_track_switch_and_return_are_told_apart() -> None:
    # Persons 1 (x 0) and 2 (x 500), frames 1-12.
    gt = _gt(range(1, 13), {1: 0.0, 2: 500.0})
    spec = []
    for f in range(1, 13):
        # Person 1: id 10 on frames 1-6, a new id 11 born on frames 7-9, id 10 back 10-12.
        spec.append((f, 11 if 7 <= f <= 9 else 10, 0.0, 0))
        # Person 2: id 20 on frames 1-8; then id 21, which was matched on nobody (x 900) on
        # frames 1-8 and jumps over (matched in the previous frame): a switch.
        spec.append((f, 20 if f <= 8 else 21, 500.0, 1))
        if f <= 8:
            spec.append((f, 21, 900.0, 2))
    rows = _rows(spec)
    people = id_errors.label(rows, gt)
    assert list(people[:3]) == [1, 2, -1]
    tracks = id_errors.tracks_of(rows, people)
    events = {(e.person, e.frame): e for e in id_errors.events_of(rows, people, tracks)}
    assert {k: (e.kind, e.old, e.new) for k, e in events.items()} == {
        (1, 7): ("new", 10, 11),
        (1, 10): ("back", 11, 10),
        (2, 9): ("new", 20, 21),  # id 21 covered nobody before: born on person 2 for the scorer
    }
    # Person 1's most frequent id is 10 (9 rows): the 3 rows under 11 are lost, to the new track.
    assert events[(1, 7)].rows_lost == 3 and events[(1, 10)].rows_lost == 0
    # Person 2: id 20 holds 8 rows, id 21 the last 4.
    assert events[(2, 9)].rows_lost == 4


def test_a_track_taken_over_from_another_person_is_a_switch_or_a_coast() -> None:
    gt = _gt(range(1, 11), {1: 0.0, 2: 500.0, 3: 1000.0})
    spec = []
    for f in range(1, 11):
        spec.append((f, 10, 0.0, 0))  # person 1: id 10 throughout
        spec.append((f, 40, 1000.0, 3) if f > 6 else (f, 30, 1000.0, 2))  # person 3
        if f <= 4:
            spec.append((f, 20, 500.0, 1))  # person 2: id 20, then lost
        elif f <= 6:
            spec.append((f, 20, 800.0, -1))  # id 20 coasting on nobody
        else:
            spec.append((f, 30, 500.0, 1))  # person 2 under id 30 from frame 7
    # Id 30 was on person 3 in frames 1-6, then takes person 2; person 3 gets id 40.
    rows = _rows(spec)
    people = id_errors.label(rows, gt)
    tracks = id_errors.tracks_of(rows, people)
    events = id_errors.events_of(rows, people, tracks)
    on2 = [e for e in events if e.person == 2]
    assert [(e.kind, e.old, e.new, e.frame) for e in on2] == [("switch", 20, 30, 7)]
    assert [(e.kind, e.old, e.new) for e in events if e.person == 3] == [("new", 30, 40)]
    # The same, with id 30 unmatched in frame 6: a lost track taking over.
    rows[(rows[:, 1] == 30) & (rows[:, 0] == 6), 6] = -1
    tracks = id_errors.tracks_of(rows, people)
    on2 = [e for e in id_errors.events_of(rows, people, tracks) if e.person == 2]
    assert [e.kind for e in on2] == ["coast"]


def test_rows_by_owner_counts_rows_off_the_persons_main_id() -> None:
    gt = _gt(range(1, 9), {1: 0.0, 2: 500.0})
    spec = [(f, 10, 0.0, 0) for f in range(1, 7)] + [(f, 11, 0.0, -1) for f in (7, 8)]
    spec += [(f, 20, 500.0, 1) for f in range(1, 9)]
    rows = _rows(spec)
    people = id_errors.label(rows, gt)
    got = id_errors.rows_by_owner(rows, people)
    assert got == {("fragment", "coasted"): 2}


def test_relabelled_rows_put_each_person_under_one_id_and_drop_the_rest() -> None:
    gt = _gt(range(1, 5), {1: 0.0, 7: 500.0})
    # Person 1 under ids 3 then 4; person 7 under id 1 (a gt id of another person); id 9 on
    # nobody (x 900) and id 1 on nobody in frame 4.
    spec = [(f, 3 if f <= 2 else 4, 0.0, 0) for f in range(1, 5)]
    spec += [(f, 1, 500.0, 1) for f in range(1, 4)] + [(4, 1, 900.0, 1)]
    spec += [(f, 9, 900.0, -1) for f in range(1, 4)]
    rows = _rows(spec)
    people = id_errors.label(rows, gt)
    perfect, no_fp = id_errors.relabelled(rows, people)
    on = people >= 0
    assert list(perfect[on, 1]) == list(people[on])  # every row on a person under its id
    off_ids = set(perfect[~on, 1].astype(int))
    assert off_ids == {1 + 8, 9 + 8}  # track ids moved past every person's (7 + 1)
    assert not off_ids & {1, 7}
    assert len(no_fp) == int(on.sum()) and set(no_fp[:, 1].astype(int)) == {1, 7}
    assert np.array_equal(perfect[:, [0, 2, 3, 4, 5]], rows[:, [0, 2, 3, 4, 5]])  # same boxes
    assert np.all(perfect[:, 6] == 1.0)
