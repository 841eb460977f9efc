"""ctypes access to the optimised firmware controllers (build/lib/libhdcontrol.so).

Struct layouts mirror firmware/core/hd_{pid,vel_observer,biquad,trajectory}.h.
"""
from __future__ import annotations

import ctypes as C
import subprocess
from pathlib import Path

#: The checkout these tests run in.
REPO_ROOT = Path(__file__).resolve().parents[2]

SO = REPO_ROOT / "build" / "lib" / "libhdcontrol.so"


class PidCfg(C.Structure):
    _fields_ = [("kp", C.c_int32), ("ki_dt", C.c_int32), ("kd_fs", C.c_int32), ("d_alpha", C.c_int32),
                ("shift", C.c_uint32), ("out_min", C.c_int32), ("out_max", C.c_int32)]


class Pid(C.Structure):
    _fields_ = [("integ", C.c_int64), ("dfilt", C.c_int64), ("meas_prev", C.c_int32), ("p", C.c_int32),
                ("i", C.c_int32), ("d", C.c_int32), ("out", C.c_int32), ("saturated", C.c_uint32),
                ("primed", C.c_uint32)]


class ObsCfg(C.Structure):
    _fields_ = [("kp_dt", C.c_int32), ("ki_dt", C.c_int32)]


class Obs(C.Structure):
    _fields_ = [("theta", C.c_int64), ("frac", C.c_int32), ("vel", C.c_int64), ("err", C.c_int32)]


class BqCoef(C.Structure):
    _fields_ = [(n, C.c_int32) for n in ("b0", "b1", "b2", "a1", "a2")]


class BqState(C.Structure):
    _fields_ = [("x1", C.c_int32), ("x2", C.c_int32), ("y1", C.c_int32), ("y2", C.c_int32),
                ("e1", C.c_int32), ("e2", C.c_int32)]


class TrajCfg(C.Structure):
    _fields_ = [("vmax", C.c_int32), ("amax", C.c_int32), ("jmax", C.c_int32),
                ("appr_dir", C.c_int32), ("appr_dist", C.c_int32), ("appr_vmax", C.c_int32),
                ("appr_dwell", C.c_uint32)]


class Traj(C.Structure):
    _fields_ = [("mode", C.c_int32), ("p48", C.c_int64), ("v48", C.c_int64), ("a48", C.c_int64),
                ("j48", C.c_int64), ("target48", C.c_int64), ("dir", C.c_int32), ("k", C.c_uint32),
                ("tj", C.c_uint32), ("ta", C.c_uint32), ("tv", C.c_uint32), ("tn", C.c_uint32),
                ("ins_k", C.c_uint32), ("ins_a", C.c_int64), ("vfrac", C.c_uint32), ("vfrac_acc", C.c_uint32),
                ("cruise_r", C.c_int64), ("cruise_acc", C.c_int64),
                ("goal48", C.c_int64), ("appr_leg", C.c_int32), ("appr_wait", C.c_uint32),
                ("rate_target", C.c_int32),
                ("rate_cur", C.c_int32), ("rate_dv", C.c_int32), ("rate_rem", C.c_int32),
                ("center", C.c_int64), ("amp", C.c_int32), ("w_q16", C.c_int32), ("phase", C.c_uint64),
                ("inc_q", C.c_uint64), ("inc_r", C.c_uint32), ("inc_acc", C.c_uint32),
                ("pos", C.c_int64), ("vel", C.c_int32), ("acc", C.c_int32)]


def load() -> C.CDLL:
    """Build (make) and load the library, declaring the prototypes used by the tests."""
    subprocess.run(["make", "--no-print-directory", "build/lib/libhdcontrol.so"], cwd=REPO_ROOT, check=True,
                   stdout=subprocess.DEVNULL)
    lib = C.CDLL(str(SO))
    P = C.POINTER
    lib.hd_pid_step.restype = C.c_int32
    lib.hd_pid_step.argtypes = [P(Pid), P(PidCfg), C.c_int32, C.c_int32, C.c_int32]
    lib.hd_pid_reset.argtypes = [P(Pid)]
    lib.hd_velobs_reset.argtypes = [P(Obs), C.c_int64]
    lib.hd_velobs_step.argtypes = [P(Obs), P(ObsCfg), C.c_int64]
    lib.hd_velobs_design.argtypes = [P(ObsCfg), C.c_int32, C.c_int32]
    lib.hd_velobs_vel_out.restype = C.c_int32
    lib.hd_velobs_vel_out.argtypes = [P(Obs)]
    lib.hd_biquad_reset.argtypes = [P(BqState)]
    lib.hd_biquad_step.restype = C.c_int32
    lib.hd_biquad_step.argtypes = [P(BqState), P(BqCoef), C.c_int32]
    lib.hd_traj_reset.argtypes = [P(Traj), C.c_int64]
    lib.hd_traj_ptp.restype = C.c_int32
    lib.hd_traj_ptp.argtypes = [P(Traj), P(TrajCfg), C.c_int64]
    lib.hd_traj_rate.argtypes = [P(Traj), P(TrajCfg), C.c_int32]
    lib.hd_traj_sine.restype = C.c_int32
    lib.hd_traj_sine.argtypes = [P(Traj), C.c_int64, C.c_int32, C.c_int32]
    lib.hd_traj_step.argtypes = [P(Traj), P(TrajCfg)]
    lib.hd_traj_done.restype = C.c_int32
    lib.hd_traj_done.argtypes = [P(Traj)]
    return lib
