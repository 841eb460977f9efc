"""The hdservo drive's CiA 402 walk follows python canopen's 402 state machine (hdservo.drive.plan_402).

A fake drive applies each controlword with the transition table of CiA 402 (canopen's
:class:`~canopen.profiles.p402.State402`), either at once (a drive whose time runs) or only
when the host lets a loop period pass (``settle``: a SYNC in lock-step).
"""
from __future__ import annotations

from typing import Any

import pytest
from canopen.profiles.p402 import State402

from hdservo.drive import Drive, DriveError, plan_402

#: a statusword of each state (bits of State402.SW_MASK)
SW = {name: val for name, (_, val) in State402.SW_MASK.items()}
CW_OF = {(a, b): cw for (a, b), cw in State402.TRANSITIONTABLE.items()}


class FakeDrive:
    """Statusword / controlword of a CiA 402 drive behind Drive.read / Drive.write."""

    def __init__(self, state: str, lockstep: bool = False, stuck: bool = False) -> None:
        self.state = state
        self.lockstep = lockstep
        self.stuck = stuck
        self.pending: list[int] = []
        self.writes: list[tuple[int, int, int]] = []
        self.settles = 0

    def apply(self, cw: int) -> None:
        if self.stuck:
            return
        for (a, b), c in CW_OF.items():
            if a == self.state and c == cw:
                self.state = b
                return

    def read(self, index: int, sub: int = 0) -> Any:
        assert (index, sub) == (0x6041, 0)
        return SW[self.state]

    def write(self, index: int, sub: int, value: Any) -> None:
        self.writes.append((index, sub, int(value)))
        if index == 0x6040:
            if self.lockstep:
                self.pending.append(int(value))
            else:
                self.apply(int(value))

    def settle(self) -> None:
        self.settles += 1
        while self.pending:
            self.apply(self.pending.pop(0))


def _drive(fake: FakeDrive) -> Drive:
    d = Drive.__new__(Drive)            # no bus: the SDO access is the fake's
    d.read = fake.read                  # type: ignore[method-assign]
    d.write = fake.write                # type: ignore[method-assign]
    return d


def _cws(fake: FakeDrive) -> list[int]:
    return [v for i, _, v in fake.writes if i == 0x6040]


@pytest.mark.parametrize("start", ["SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON", "OPERATION ENABLED",
                                   "QUICK STOP ACTIVE"])
def test_enable_reaches_operation_enabled_through_ready(start: str) -> None:
    fake = FakeDrive(start)
    _drive(fake).enable("CYCLIC SYNCHRONOUS TORQUE")
    assert fake.state == "OPERATION ENABLED"
    assert fake.writes[0] == (0x6060, 0, 10)
    cws = _cws(fake)
    assert cws[-2:] == [State402.CW_SWITCH_ON, State402.CW_OPERATION_ENABLED]
    assert State402.CW_SHUTDOWN in cws or start == "READY TO SWITCH ON"   # switched on afresh


def test_plan_matches_canopen_transitions() -> None:
    assert plan_402("SWITCH ON DISABLED", "OPERATION ENABLED") == [0x06, 0x07, 0x0F]
    assert plan_402("OPERATION ENABLED", "OPERATION ENABLED") == [0x06, 0x07, 0x0F]
    assert plan_402("OPERATION ENABLED", "SWITCH ON DISABLED") == [State402.CW_DISABLE_VOLTAGE]
    assert plan_402("QUICK STOP ACTIVE", "OPERATION ENABLED") == [0x00, 0x06, 0x07, 0x0F]
    assert plan_402("SWITCH ON DISABLED", "SWITCH ON DISABLED") == []
    for bad in ("FAULT", "NOT READY TO SWITCH ON", "NO SUCH STATE"):
        with pytest.raises(DriveError):
            plan_402("SWITCH ON DISABLED", bad)


def test_disable_from_operation_enabled() -> None:
    fake = FakeDrive("OPERATION ENABLED")
    _drive(fake).disable()
    assert fake.state == "SWITCH ON DISABLED" and _cws(fake) == [0x00]


def test_fault_is_refused_until_reset() -> None:
    fake = FakeDrive("FAULT")
    with pytest.raises(DriveError, match="FAULT"):
        _drive(fake).enable()
    assert _cws(fake) == []


def test_lockstep_settles_after_each_controlword() -> None:
    """In lock-step the drive acts on a controlword only in its next loop period: the walk lets
    one pass (``settle``) after each controlword, then polls with one between reads."""
    fake = FakeDrive("SWITCH ON DISABLED", lockstep=True)
    _drive(fake).enable("CYCLIC SYNCHRONOUS POSITION", settle=fake.settle)
    assert fake.state == "OPERATION ENABLED"
    assert fake.settles == 3 and _cws(fake) == [0x06, 0x07, 0x0F]


def test_a_drive_that_does_not_follow_is_reported() -> None:
    fake = FakeDrive("SWITCH ON DISABLED", lockstep=True, stuck=True)
    with pytest.raises(DriveError, match="did not reach OPERATION ENABLED"):
        _drive(fake).enable(settle=fake.settle, timeout=0.2)
    assert fake.settles == 3 + 10
    fake2 = FakeDrive("SWITCH ON DISABLED", stuck=True)
    with pytest.raises(DriveError, match="did not reach OPERATION ENABLED"):
        _drive(fake2).enable(timeout=0.05)


def test_unknown_mode_refused_before_any_write() -> None:
    fake = FakeDrive("SWITCH ON DISABLED")
    with pytest.raises(DriveError, match="mode must be one of"):
        _drive(fake).enable("HOMING")
    assert fake.writes == []
