"""The M-of-N confirmation a new lock needs (``LockConfirmation``), on its own: fixes that agree, in most frames."""

from __future__ import annotations

from app.messages import TargetObservation
from app.missions.fix_checks import FixChecks, LockConfirmation

COV = ((0.01, 0.0), (0.0, 0.01))
FRAME_S = 1.0 / 15.0


def fix(t_s: float, n_m: float, e_m: float = 0.0) -> TargetObservation:
    return TargetObservation(t_s, (n_m, e_m, 0.0), COV)


def test_three_agreeing_fixes_in_three_frames_confirm_on_the_third() -> None:
    lock = LockConfirmation(FixChecks())  # 3 fixes within 0.5 m in 1 s, ≥ 30 % of its frames
    answers = []
    for i in range(3):
        t_s = i * FRAME_S
        lock.on_frame(t_s)
        answers.append(lock.confirmed(fix(t_s, 10.0 + 0.1 * i)))
    assert answers == [False, False, True]
    lock.on_frame(3 * FRAME_S)
    assert not lock.confirmed(fix(3 * FRAME_S, 10.0))  # confirming cleared the candidates: one fix again


def glint_answers(checks: FixChecks) -> list[bool]:
    """A glint in 3 of 15 frames (20 %), always in the same place: what each of its fixes gets."""
    lock = LockConfirmation(checks)
    answers = []
    for i in range(15):
        t_s = i * FRAME_S
        lock.on_frame(t_s)
        if i % 5 == 4:
            answers.append(lock.confirmed(fix(t_s, 3.0)))
    return answers


def test_fixes_that_agree_in_too_few_of_the_frames_do_not_confirm() -> None:
    assert glint_answers(FixChecks()) == [False, False, False]  # 20 % < 30 %: no object
    assert glint_answers(FixChecks(confirm_fraction=0.0)) == [False, False, True]  # no share required: confirmed


def test_fixes_farther_apart_than_the_radius_or_the_window_do_not_confirm() -> None:
    checks = FixChecks()
    apart = LockConfirmation(checks)
    for i, n_m in enumerate((0.0, checks.confirm_radius_m * 1.1, -checks.confirm_radius_m * 1.1)):
        apart.on_frame(i * FRAME_S)
        assert not apart.confirmed(fix(i * FRAME_S, n_m))
    slow = LockConfirmation(checks)
    for i in range(3):  # one fix every 0.6 s: the first has left the 1 s window when the third comes
        t_s = i * 0.6
        slow.on_frame(t_s)
        assert not slow.confirmed(fix(t_s, 5.0))
