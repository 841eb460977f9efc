"""Compensation download: an identified model mapped onto drive parameters and tables.

:func:`plan_download` maps an identified model (``hdservo identify -o MODEL.toml``)
onto the axis keys :func:`hdservo.compsetup.compensator_params` reads and computes
the drive parameters, the parameter groups 0x5100:2 (friction) / 0x5100:3 (TE) and
the Preisach image 0x5100:1; keys the model lacks come from an axis file.
:func:`write_verified` writes a plan to a drive with the power stage off and reads
every item back.  ``hdservo download`` (:mod:`hdservo.commands.download`) is the
command around them.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

from .errors import UserError


class DownloadTransportError(UserError):
    """A download broken off at the protocol level on every repeat (time-outs, stale frames on a
    loaded host): the drive refused nothing, so the same download on a fresh connection may succeed."""


#: parameters written by SDO one by one (the groups of 0x5100:2/3 go as tables)
SDO_PREFIXES = ("cb_ramp_ticks", "cb_dpos_fc", "cp_", "mx_", "pr_", "bs_", "dob_", "te_k1", "te_out_", "fe_share")


# ----------------------------------------------------------------- model -> compsetup keys


def read_model(path: Path) -> dict[str, dict[str, Any]]:
    """The checked model (:func:`hdservo.ident.model_reader.read_model`); one-line UserError when bad."""
    from .ident.model_reader import read_model as _read
    return _read(path)


def motor_share(model: Mapping[str, Mapping[str, Any]]) -> float | None:
    """Motor side's share of the identified total friction, 0..1, or None when the model cannot tell.

    The locked-output presliding experiment measures the motor-side breakaway alone (motor units); the
    friction sweep the output-referred total.  share = N (b+ + b-) / (Fs+ + Fs-), at most 1.
    """
    ft, fm = model.get("friction_total") or {}, model.get("friction_motor") or {}
    try:
        n = float(model["gear"]["ratio"])
        b = float(fm["presliding_breakaway_pos_Nm"]) + float(fm["presliding_breakaway_neg_Nm"])
        fs = float(ft["fs_pos_Nm"]) + float(ft["fs_neg_Nm"])
    except (KeyError, TypeError, ValueError):
        return None
    if not (b > 0 and fs > 0 and n > 0) or not math.isfinite(b / fs):
        return None
    return min(1.0, n * b / fs)


def model_overrides(model: Mapping[str, Mapping[str, Any]], axis_get) -> tuple[dict[str, float], list[str]]:
    """``{"section.key": value}`` for :func:`compsetup.compensator_params` and notes on what was assumed."""
    notes: list[str] = []
    n = float(model["gear"]["ratio"])
    if not n > 0:
        raise UserError("model: [gear] ratio must be > 0")
    o: dict[str, float] = {"gear.ratio": n}
    ft = model.get("friction_total")
    fm = model.get("friction_motor", {})
    if ft:
        need = ("fc_pos_Nm", "fc_neg_Nm", "fs_pos_Nm", "fs_neg_Nm", "vs_rad_s", "viscous_Nms_per_rad")
        miss = [k for k in need if k not in ft]
        if miss:
            raise UserError(f"model: [friction_total] lacks {', '.join(miss)}")
        # the identified friction is the total, output-referred: one lumped side (motor keys, motor units)
        o.update({"friction_motor.enabled": 1.0, "friction_load.enabled": 0.0,
                  "friction_motor.fc_pos_Nm": ft["fc_pos_Nm"] / n, "friction_motor.fc_neg_Nm": ft["fc_neg_Nm"] / n,
                  "friction_motor.fs_pos_Nm": ft["fs_pos_Nm"] / n, "friction_motor.fs_neg_Nm": ft["fs_neg_Nm"] / n,
                  "friction_motor.vs_rad_s": ft["vs_rad_s"] * n,
                  "friction_motor.viscous_Nms_per_rad": ft["viscous_Nms_per_rad"] / n ** 2,
                  "friction_motor.delta": 2.0})
        if "delta" in ft:               # the fitted shape of the plant's drop (the drive's map runs delta 2)
            from .compsetup import FRICTION_DELTA_KEY
            o[FRICTION_DELTA_KEY] = float(ft["delta"])
        share = motor_share(model)
        if share is not None:
            from .compsetup import MOTOR_SHARE_KEY
            o[MOTOR_SHARE_KEY] = share
            notes.append(f"Stribeck levels: the motor side's share {share:.3g} of the total friction "
                         "(presliding breakaway x N / total Fs)")
        if "sigma0_Nm_per_rad" in fm:
            o["friction_motor.lugre_enabled"] = 1.0
            o["friction_motor.sigma0_Nm_per_rad"] = float(fm["sigma0_Nm_per_rad"])
            if "sigma1_Nms_per_rad" in fm:
                o["friction_motor.sigma1_Nms_per_rad"] = float(fm["sigma1_Nms_per_rad"])
            else:
                jm = float(model.get("motor", {}).get("jm_kgm2", axis_get("motor.jm_kgm2")))
                o["friction_motor.sigma1_Nms_per_rad"] = math.sqrt(fm["sigma0_Nm_per_rad"] * jm)
                notes.append("sigma1 not identified: rule sqrt(sigma0 J_m)")
        else:
            o["friction_motor.lugre_enabled"] = 0.0
            o["friction_motor.sigma0_Nm_per_rad"] = 0.0
            o["friction_motor.sigma1_Nms_per_rad"] = 0.0
            notes.append("no presliding in the model: LuGre sigma0 at the firmware's stiff default")
    else:
        notes.append("no [friction_total] in the model: friction from --axis")
    st = model.get("stiffness")
    if st and "k1_Nm_per_rad" in st:        # an FRF-only model has the damping alone: K1 from --axis
        o["stiffness.enabled"] = 1.0
        o["stiffness.k1_Nm_per_rad"] = float(st["k1_Nm_per_rad"])
        for k in ("k2_Nm_per_rad", "k3_Nm_per_rad", "t1_Nm", "t2_Nm"):   # the three-slope curve (compliance)
            if k in st:
                o[f"stiffness.{k}"] = float(st[k])
    hm = model.get("hysteresis_maxwell")
    if hm:
        o["hysteresis_maxwell.enabled"] = 1.0
        o["hysteresis_maxwell.n_elements"] = float(hm.get("n_elements", 0))
        for i in range(1, int(hm.get("n_elements", 0)) + 1):      # the checked elements, not stray keys
            for k in (f"e{i}_k_Nm_per_rad", f"e{i}_w_Nm"):
                o[f"hysteresis_maxwell.{k}"] = float(hm[k])
        # the identified hysteresis is in the Maxwell elements / the Preisach image, not the plant's Preisach keys
        o["hysteresis_preisach.enabled"] = 0.0
    lmo = model.get("lost_motion")
    if lmo is not None:
        # identified lost-motion elements (twist on the output travel): the Maxwell-slip compensator
        # takes them instead of a presliding curve of the (not identified) output-side friction
        o["lost_motion.n_elements"] = float(lmo.get("n_elements", 0))
        for i in range(1, int(lmo.get("n_elements", 0)) + 1):
            for k in (f"e{i}_gain", f"e{i}_d_rad"):
                o[f"lost_motion.{k}"] = float(lmo[k])
    te = model.get("transmission_error")
    if te:
        harm = []
        i = 1
        while f"wg{i}_order" in te:
            harm.append((abs(float(te[f"wg{i}_amp_rad"])), int(te[f"wg{i}_order"]), float(te[f"wg{i}_amp_rad"]),
                         float(te[f"wg{i}_phase_rad"])))
            i += 1
        harm.sort(reverse=True)
        o["transmission_error.enabled"] = 1.0
        for j in range(4):
            _, order, amp, ph = harm[j] if j < len(harm) else (0.0, 0, 0.0, 0.0)
            o[f"transmission_error.wg{j + 1}_order"] = float(order)
            o[f"transmission_error.wg{j + 1}_amp_rad"] = amp
            o[f"transmission_error.wg{j + 1}_phase_rad"] = ph
        if len(harm) > 4:
            notes.append(f"TE: the 4 largest of {len(harm)} harmonics (firmware holds 4)")
        i = 1
        while f"out{i}_order" in te:            # output-side lines (the axis file's are not the model's)
            for k in ("order", "amp_rad", "phase_rad"):
                o[f"transmission_error.out{i}_{k}"] = float(te[f"out{i}_{k}"])
            i += 1
        for j in range(i, 5):
            o[f"transmission_error.out{j}_order"] = 0.0
            o[f"transmission_error.out{j}_amp_rad"] = 0.0
            o[f"transmission_error.out{j}_phase_rad"] = 0.0
    g = model.get("gravity")
    if g and "mgl_Nm" in g:
        o["gravity.enabled"] = 1.0
        o["gravity.mgl_Nm"] = float(g["mgl_Nm"])
        o["gravity.offset_rad"] = float(g.get("offset_rad", 0.0))
    if "jl_kgm2" in model.get("load", {}):
        o["load.jl_kgm2"] = float(model["load"]["jl_kgm2"])
    if "jm_kgm2" in model.get("motor", {}):
        o["motor.jm_kgm2"] = float(model["motor"]["jm_kgm2"])
    return o, notes


def plan_download(model_path: Path, axis: str = "reference", preisach: Path | None = None,
                  version: int = 1, vel_kp: float | None = None, torque_limit: float | None = None) -> dict[str, Any]:
    """Everything to write: ``params`` (name -> table unit), ``groups`` (sub -> raw dict), ``preisach`` bytes.

    ``vel_kp`` (N.m.s/rad) is the velocity-loop gain the drive runs with the download (default: the
    design rule's for the model's total inertia); it sets the crossover of the twist torque rule
    (:func:`hdservo.compsetup.twist_torque_source`).  ``torque_limit`` (N.m) is the drive's output torque
    limit, the backstepping law's clamp ``bs_u_max`` (default: the parameter's default).

    Raises
    ------
    UserError
        Unreadable model, a value outside a parameter's range, a bad Preisach image.
    """
    from . import compsetup, resources, sim
    from .drive import TABLE_GROUPS
    from .params_gen import BY_NAME as PARAMS
    from .ident.model_reader import preisach_table_file
    from .preisach_table import PreisachTable
    model = read_model(model_path)
    # a shipped axis' name ("csf17_50") is its file, as for every --sim AXIS
    ax = axis if axis in ("reference", "minimal") else str(Path(resources.axis_arg(axis)).resolve())
    if ax not in ("reference", "minimal") and not Path(ax).is_file():
        raise UserError(f"{axis}: axis file not found")
    over, notes = model_overrides(model, lambda k: float(sim.axis_param(k, ax)))
    try:
        cp = compsetup.compensator_params(ax, model=over, vel_kp=vel_kp, torque_limit=torque_limit)
    except (ValueError, KeyError, ZeroDivisionError, TypeError, OverflowError) as e:
        raise UserError(f"{model_path}: cannot compute the compensator parameters: {e}") from None
    cp.pop("cb_enable", None)
    f_load = compsetup.load_resonance_hz(float(over.get("stiffness.k1_Nm_per_rad", sim.axis_param("stiffness.k1_Nm_per_rad", ax))),
                                         float(cp.get("pr_jl", 0.0)))
    jt = float(cp.get("pr_jl", 0.0)) + float(cp.get("pr_jm", 0.0))
    f_v = compsetup.velocity_loop_hz(compsetup.design_vel_kp(jt) if vel_kp is None else vel_kp, jt) if jt > 0 else math.inf
    notes.append(f"twist torque estimate: {'the motor side while it slides' if cp.get('pr_t_src') == 2 else 'the model'} "
                 f"(pr_t_src {int(cp.get('pr_t_src', 1))}; load resonance {f_load:.3g} Hz, motor side below "
                 f"{compsetup.RESONANCE_LOOP_RATIO:g} x the {f_v:.3g} Hz velocity loop = "
                 f"{compsetup.RESONANCE_LOOP_RATIO * f_v:.3g} Hz)")
    params: dict[str, float] = {}
    for name, v in cp.items():
        p = PARAMS.get(name)
        if p is None:
            continue
        if not math.isfinite(float(v)):
            raise UserError(f"{model_path}: {name} is not finite")
        val = min(max(float(v), p.min), p.max) if name in ("lug_sigma0", "mx_stiffness") else float(v)
        if not p.min <= val <= p.max:
            raise UserError(f"{model_path}: {name} = {val:.6g} {p.unit} outside the drive's range "
                            f"[{p.min:g}, {p.max:g}]")
        params[name] = val
    groups: dict[int, dict[str, int]] = {}
    for sub, (_, names) in TABLE_GROUPS.items():
        groups[sub] = {n: raw_of(n, params[n]) for n in names}
    sdo = {k: v for k, v in params.items() if k.startswith(SDO_PREFIXES)}
    blob = None
    ptab = preisach
    if ptab is None:
        name = preisach_table_file(model)
        if name:
            ptab = model_path.parent / name
    if ptab is not None:
        if not ptab.is_file():
            where = "[preisach_drive_table] file" if "preisach_drive_table" in model else "[identified] preisach_table"
            raise UserError(f"{ptab}: Preisach table file not found"
                            + ("" if preisach is not None else f" (named by {model_path} {where})"))
        try:
            try:
                blob = ptab.read_bytes()
            except OSError as e:
                raise UserError(f"{ptab}: cannot read: {e.strerror or e}") from None
            try:
                PreisachTable.from_bytes(blob)
            except UserError as e:
                raise UserError(f"{ptab}: {e}") from None
        except UserError as e:
            raise UserError(f"{e}; nothing downloaded") from None
    return {"params": params, "sdo": sdo, "groups": groups, "preisach": blob, "preisach_file": ptab,
            "notes": notes, "overrides": over, "version": version}


def raw_of(name: str, value: float) -> int:
    """Raw word of a drive parameter (:func:`hdservo.driveconfig.raw_of`, as :meth:`Drive.set_param`)."""
    from .driveconfig import raw_of as _raw
    from .params_gen import BY_NAME as PARAMS
    return _raw(PARAMS[name], value)


def write_verified(drive: Any, plan: Mapping[str, Any], tables: bool = True,
                   progress=lambda m: None, skip_missing: bool = False) -> dict[str, Any]:
    """Write the plan to the drive (power stage off) and read every item back.

    Raises
    ------
    UserError
        The drive refuses a write (SDO abort: range, table check, power on) or
        a read-back differs.
    DownloadTransportError
        (a UserError) A table transfer broke at the protocol level on every repeat.
    """
    from .drive import DriveError, DriveProtocolError
    from .params_gen import BY_NAME as PARAMS
    done: dict[str, Any] = {"params": 0, "tables": [], "missing": []}
    try:
        st = drive.state()
        if st == "OPERATION ENABLED":
            raise UserError("the drive's power stage is on (OPERATION ENABLED): disable it before downloading")
        progress(f"parameters: {len(plan['sdo'])} by SDO")
        # a value inside its own range that the drive refuses (0x06090030) breaks a check across parameters
        # against a value still in force (cp_t1 above the old cp_t2, cb_pki_vlo above the old cb_pki_vhi):
        # it is written again after the others, once
        deferred: list[str] = []
        for pass_no, names in enumerate((list(plan["sdo"]), deferred)):
            for name in names:
                v = plan["sdo"][name]
                p = PARAMS[name]
                raw = raw_of(name, v)
                if skip_missing and p.index not in drive.node.sdo:
                    done["missing"].append(name)
                    continue
                try:
                    drive.write(p.index, p.sub, raw)
                except DriveError as e:
                    if skip_missing and ("0x06090011" in str(e) or "0x06020000" in str(e)):
                        done["missing"].append(name)     # older drive firmware: parameter not in its dictionary
                        continue
                    if pass_no == 0 and "0x06090030" in str(e) and not isinstance(e, DriveProtocolError):
                        deferred.append(name)
                        continue
                    raise
                back = int(drive.read(p.index, p.sub))
                if back != raw:
                    raise UserError(f"{name} (0x{p.index:04X}:{p.sub}): read back {back}, wrote {raw}")
                done["params"] += 1
        if tables:
            for sub, raw in plan["groups"].items():
                label = {2: "friction group (Stribeck + LuGre)", 3: "TE group"}[sub]
                progress(f"0x5100:{sub} {label}")
                # read back: the group in force (domain upload) must equal what was written, byte for byte
                # (the 0x28xx SDO entries are not compared: the adapter does not mirror a group into them)
                drive.download_group(sub, raw, version=int(plan["version"]))
                done["tables"].append(sub)
            if plan.get("preisach") is not None:
                progress("0x5100:1 Preisach/Everett table")
                drive.download_table(1, plan["preisach"])
                done["tables"].append(1)
    except DriveProtocolError as e:
        raise DownloadTransportError(f"download broken off at the protocol level (not refused): {e}") from None
    except DriveError as e:
        raise UserError(f"download refused by the drive: {e}") from None
    except ValueError as e:        # raw value does not fit the object's type (python canopen)
        raise UserError(f"download: {e}") from None
    return done
