"""Firmware facts for the host, generated from the C headers by tools/gen_fw_const.py.

Do not edit: change the C and run ``tools/gen_fw_const.py``.
"""
from __future__ import annotations

#: control loop rate, Hz (firmware/core/hd_units.h HD_LOOP_HZ)
LOOP_HZ = 10000
#: control period, s
LOOP_DT_S = 1.0 / LOOP_HZ

#: fraction bits of the fixed-point signal formats (firmware/core/hd_units.h)
FRAC_BITS = {"angle": 32, "vel_out": 32, "vel_mot": 24, "acc": 24, "torque": 16, "current": 16}

#: capture signal ids (hd_sig_t, firmware/app/hd_app.h)
SIGNALS = {"tick": 0, "pos_out_lo": 1, "pos_out_hi": 2, "pos_mot_lo": 3, "pos_mot_hi": 4, "vel_out": 5, "vel_mot": 6, "pos_ref_lo": 7, "pos_ref_hi": 8, "vel_ref": 9, "acc_ref": 10, "torque_cmd": 11, "current": 12, "gyro": 13, "exc": 14, "pos_err": 15, "fault": 16}
SIGNAL_COUNT = 17

#: application fault codes (hd_fault_t, firmware/app/hd_app.h)
FAULTS = {"none": 0, "torque_sat": 1, "overspeed": 2, "travel": 3, "following": 4, "enc_jump": 5, "sensor": 6, "param": 7, "comm": 8}
#: fault code -> name (upper case, as the drive's documentation writes it)
FAULT_NAMES = {0: "NONE", 1: "TORQUE_SAT", 2: "OVERSPEED", 3: "TRAVEL", 4: "FOLLOWING", 5: "ENC_JUMP", 6: "SENSOR", 7: "PARAM", 8: "COMM"}
#: fault code -> EMCY error code (firmware/canopen/hd_app_co.c hd_app_co_emcy_for_fault)
FAULT_EMCY = {1: 0x2310, 2: 0x8400, 3: 0x8612, 4: 0x8611, 5: 0x7305, 6: 0x7300, 7: 0x6320, 8: 0x8130}

#: drive modes (hd_mode_t, firmware/app/hd_app.h)
MODES = {"off": 0, "torque": 1, "velocity": 2, "position": 3, "ptp": 4, "rate": 5, "sine": 6, "excitation": 7, "stab": 8}
#: excitation injection points (hd_inj_t, firmware/app/hd_app.h)
INJECTION = {"torque": 0, "vel_ref": 1, "pos_ref": 2, "torque_ff": 3}
#: excitation kinds (hd_exc_kind_t, firmware/core/hd_excitation.h)
EXCITATION = {"none": 0, "vsteps": 1, "tramp": 2, "forc": 3, "chirp": 4, "multisine": 5, "prbs": 6}
#: parameter-store boot status (hd_pstore_status_t, firmware/app/hd_param_store.h)
PSTORE_STATUS = {0: "OK", 1: "BLANK", 2: "CORRUPT", 3: "INCOMPATIBLE", 4: "NVM_ERROR"}
