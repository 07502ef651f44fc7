"""What the evaluation counts as an off-target touchdown: every time the vehicle came down onto the water farther
than the capture radius from the object (grab or not), and grabs made that far just above the water."""

from __future__ import annotations

from types import SimpleNamespace

from sim.evaluate_pickup import _off_target_touchdowns
from sim.pickup_world import CONTACT_CLEAR_M, CONTACT_M, DECK_RADIUS_M, PickupOutcome, PickupWorld


def contacts_of(track: list[tuple[float, float, tuple[float, float]]]) -> list[dict]:
    """Feed (t, height over the water, vehicle NE) samples, the object at (20, 0), to ``PickupWorld._note_contact``."""
    world = SimpleNamespace(outcome=PickupOutcome(), _on_water=False)  # nothing caught
    for t_s, height_m, (n, e) in track:
        PickupWorld._note_contact(world, t_s, height_m, (n, e, 0.0), (20.0, 0.0, 0.0))  # type: ignore[arg-type]
    return world.outcome.contacts


def test_each_time_down_on_the_water_counts_once_with_its_distance_to_the_object():
    bounce = CONTACT_CLEAR_M / 2  # a crest lifts it a little: still the same touchdown
    track = [(0.0, 2.0, (20.4, 0.0)), (1.0, CONTACT_M, (20.4, 0.0)), (1.5, bounce, (20.4, 0.0)),
             (2.0, 0.0, (20.3, 0.0)), (3.0, 1.0, (20.0, 0.0)), (4.0, 0.01, (20.1, 0.0))]  # fmt: skip
    contacts = contacts_of(track)
    assert [c["t_s"] for c in contacts] == [1.0, 4.0]
    assert abs(contacts[0]["error_m"] - 0.4) < 1e-9 and abs(contacts[1]["error_m"] - 0.1) < 1e-9


def test_the_deck_is_no_touchdown():
    assert contacts_of([(0.0, 0.0, (DECK_RADIUS_M - 0.5, 0.0)), (5.0, 0.0, (1.0, 1.0))]) == []


def test_off_target_touchdowns_are_contacts_off_the_object_and_grabs_off_it_above_the_water():
    contacts = [{"t_s": 10.0, "error_m": 0.4}, {"t_s": 30.0, "error_m": 0.1}]
    grabs = [
        {"t_s": 10.5, "error_m": 0.45},  # the same touchdown as the first contact: counted once
        {"t_s": 30.2, "error_m": 0.12},  # on the object
        {"t_s": 50.0, "error_m": 0.3},  # closed just above the water, off the object: counted
    ]
    assert _off_target_touchdowns(grabs, contacts, 0.25) == 2
    settling = [{"t_s": 31.0, "error_m": 0.28}]  # on the water a second after a grab on the object, drifted off
    assert _off_target_touchdowns(grabs, settling, 0.25) == 2  # part of the 30.2 s grab; the grabs at 10.5, 50 s count
    assert _off_target_touchdowns([], contacts, 0.25) == 1
    assert _off_target_touchdowns(grabs, contacts, 0.5) == 0


def test_after_a_grab_caught_the_object_the_water_is_no_touchdown_on_it():
    world = SimpleNamespace(outcome=PickupOutcome(caught=True), _on_water=False)
    PickupWorld._note_contact(world, 1.0, 0.0, (20.5, 0.0, 0.0), (20.0, 0.0, 0.0))  # type: ignore[arg-type]
    assert world.outcome.contacts == []
