"""``hdservo config restore`` rolls back on every failure inside the restore sequence.

The drive here is an in-memory stand-in (the CANopen behaviour is tested on the virtual
drive in test_config_cli.py): what matters is the host's sequence -- read the old values,
write and read back, and on ANY failure (a refused write, a read-back that raises
DriveError, a time-out, an OSError from the bus) put the old values back and report one
line.
"""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Callable

import pytest

from hdservo import driveconfig
from hdservo.cli import UserError
from hdservo.commands import config as cfg
from hdservo.drive import DriveError
from hdservo.params_gen import BY_NAME, TABLE_HASH

HB = (0x1017, 0)           # producer heartbeat time, a stored object
KP = BY_NAME["pos_kp"]


class FakeDrive:
    """Object dictionary in a dict; ``fail(key, exc)`` makes the first read of ``key`` after a write raise."""

    def __init__(self) -> None:
        self.od: dict[tuple[int, int], int] = {(0x5101, 5): TABLE_HASH, HB: 100, (KP.index, KP.sub): 40 << 16}
        self.written: set[tuple[int, int]] = set()
        self.armed: dict[tuple[int, int], BaseException] = {}

    def fail(self, key: tuple[int, int], exc: BaseException) -> None:
        self.armed[key] = exc

    def read(self, index: int, sub: int) -> int:
        key = (index, sub)
        if key in self.written and key in self.armed:
            raise self.armed.pop(key)
        return self.od[key]

    def write(self, index: int, sub: int, value: int) -> None:
        self.od[(index, sub)] = int(value)
        self.written.add((index, sub))

    def reconfigure(self, fn: Callable[[], None]) -> None:
        fn()


def _args(tmp_path: Path) -> argparse.Namespace:
    f = tmp_path / "drive.toml"
    f.write_text(driveconfig.to_toml({"pos_kp": 30 << 16}, TABLE_HASH, objects={HB: 250}))
    return argparse.Namespace(file=f, force=False, node_id=1, save=False)


@pytest.mark.parametrize("exc", [DriveError("SDO time-out reading 0x1017:0"), TimeoutError("no answer"),
                                 OSError(5, "Input/output error"), UserError("refused")],
                         ids=["DriveError", "TimeoutError", "OSError", "UserError"])
def test_failed_object_read_back_rolls_back(tmp_path: Path, exc: BaseException) -> None:
    drive = FakeDrive()
    before = dict(drive.od)
    drive.fail(HB, exc)
    with pytest.raises(UserError) as e:
        cfg._restore(drive, _args(tmp_path), lambda m: None)
    msg = str(e.value)
    assert "\n" not in msg and "previous values are back" in msg, msg
    assert drive.od == before, "a refused restore must change nothing"


def test_failed_param_read_back_rolls_back(tmp_path: Path) -> None:
    drive = FakeDrive()
    before = dict(drive.od)
    drive.fail((KP.index, KP.sub), ConnectionResetError(104, "Connection reset by peer"))
    with pytest.raises(UserError, match="previous values are back"):
        cfg._restore(drive, _args(tmp_path), lambda m: None)
    assert drive.od == before


def test_rollback_failure_is_reported(tmp_path: Path) -> None:
    """When putting the old values back fails too, the one line says so (and names both failures)."""
    class Stuck(FakeDrive):
        def write(self, index: int, sub: int, value: int) -> None:
            if (index, sub) == HB:
                raise DriveError("SDO abort 0x08000020")
            super().write(index, sub, value)
    drive = Stuck()
    with pytest.raises(UserError) as e:
        cfg._restore(drive, _args(tmp_path), lambda m: None)
    msg = str(e.value)
    assert "0x08000020" in msg and "putting the previous values back failed too" in msg and "\n" not in msg


def test_good_restore_writes_everything(tmp_path: Path) -> None:
    drive: Any = FakeDrive()
    out = cfg._restore(drive, _args(tmp_path), lambda m: None)
    assert "restored 1 parameters and 1 CANopen settings" in out
    assert drive.od[HB] == 250 and drive.od[(KP.index, KP.sub)] == 30 << 16
