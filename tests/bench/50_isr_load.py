#!/usr/bin/env python3
"""CPU load of the STM32G474 drive's 10 kHz control interrupt, from instruction counts.

Reads build/bench/cm4_cost.json (written by 10_cm4_cost.sh: QEMU Cortex-M4
instruction counts per kernel) and build/bench/phase_cost.json (15_phase_cost.sh:
the same kernels per phase of hd_app_step) and writes build/bench/isr_load.json:
the load at 10 kHz, the per-phase breakdown of the worst period and the slack
(cycles and microseconds left) at a control rate of 10 kHz and of 20 kHz.

At 20 kHz the current loop stays at the PWM rate (20 kHz): a control period
then carries one FOC period instead of two, one ADC interrupt instead of two
and one set of port register accesses; the frame decode and the step are the
same.

The compensator bank runs on a schedule (firmware/app/hd_sched.h): each tick of a
cycle carries its own slot of the bank's slow work.  ``isr_worst_case`` is the worst
tick of the cycle (cm4_cost.json folds the per-tick kernels ``isr_worst_case.s<k>``,
every tick measured); isr_load.json lists every tick under ``schedule``.

Worst-case control period = kernel ``isr_worst_case`` (tests/golden/gv_foc.c):
hd_app_step with every compensator of the bank enabled and set up as
control_step_full (Preisach table installed, LuGre observer and TE gains on,
weights fully on, encoders moving; PTP mode; backstepping on top of the PID is
the more expensive of the two alternatives, isr_worst_case_pid the other)
+ 2 FOC periods (20 kHz PWM) + the output-encoder frame decode.  Added as allowances
(they are register/peripheral work the emulated image cannot run):
  - interrupt entry/exit with FPU lazy stacking: 4 interrupts x 30 cycles (2 ADC, the
    DMA1_CH1 frame-received interrupt, PendSV)
  - port register access in the ISRs (ADC reads, CCR writes, encoder count): 2 x 60 cycles
  - the output-encoder read by SPI1 + DMA1 (firmware/port/stm32g474, docs/stm32g474.md):
    the CPU only programs the transfer (14 register accesses in the ADC ISR) and
    acknowledges it (6 in the DMA ISR), ~6 cycles each on the AHB/APB2 bridge = 120 cycles;
    the 48 clocks at 10.6 MHz (4.6 us) run without the CPU (before the DMA driver: a
    782-cycle busy wait)
Instructions are not cycles: the Cortex-M4 runs most data-processing
instructions in 1 cycle, loads/stores 2, taken branches 2-4, 64-bit
multiply-accumulates 1, divides 2-12; with 4 flash wait states at 170 MHz the
ART accelerator (instruction cache + prefetch) hides most of the wait states
in loops.  Assumption: 1.3 cycles per instruction on average (stated in the
JSON; the real figure needs the DWT cycle counter on the hardware, which QEMU
does not emulate).  Measures; the one budget check is the worst period of every mode
(``FE_MODES``: full-closed PTP, excitation, semi-closed with pr_t_src 2) with the online
Stribeck identification on (``with_online_estimator_modes``: its observation with and
without a sample and the feed's period, on the ticks of the bank's schedule): the script
exits 1 when any of them exceeds the 25 % target or is not measured, after writing the
JSON (the estimator must fit the interrupt in every mode; docs/firmware.md).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "build" / "bench" / "cm4_cost.json"
PHASES_SRC = ROOT / "build" / "bench" / "phase_cost.json"
DST = ROOT / "build" / "bench" / "isr_load.json"

F_CPU_HZ = 170e6
F_CTRL_HZ = 10e3
F_PWM_HZ = 20e3
CPI = 1.3
TARGET = 0.25
ALLOW_CYCLES = {"interrupt entry/exit (4 x 30: 2 ADC, DMA1_CH1, PendSV)": 120,
                "port register access (2 x 60)": 120,
                "SPI1 output-encoder read by DMA: set-up and acknowledge (20 x 6)": 120}
# per FOC (ADC) interrupt: its entry/exit and its register accesses
ALLOW_PER_FOC = 30 + 60


def slack(step_insn: int, port_per_foc: float, decode_insn: int, f_ctrl_hz: float) -> dict[str, float]:
    """Cycles of the worst control period and the slack at one control rate.

    Parameters
    ----------
    step_insn : int
        Instructions of the control step (hd_app_step) in its worst period.
    port_per_foc : float
        Instructions of one FOC period (port work: encoder, angle, ADC scaling, hd_foc_step).
    decode_insn : int
        Instructions of the output-encoder frame decode (once per control period).
    f_ctrl_hz : float
        Control rate, Hz (the FOC runs at F_PWM_HZ, at least once per control period).

    Returns
    -------
    dict[str, float]
        ``foc_periods``, ``instructions``, ``cycles``, ``cycles_available``,
        ``cpu_load`` (fraction), ``slack_cycles`` and ``slack_us`` (microseconds).
    """
    n_foc = max(1, round(F_PWM_HZ / f_ctrl_hz))
    insn = step_insn + n_foc * port_per_foc + decode_insn
    allow = sum(ALLOW_CYCLES.values()) - 2 * ALLOW_PER_FOC + n_foc * ALLOW_PER_FOC
    cycles = insn * CPI + allow
    budget = F_CPU_HZ / f_ctrl_hz
    return {"foc_periods": n_foc, "instructions": round(insn), "allowance_cycles": allow,
            "cycles": round(cycles), "cycles_available": round(budget),
            "cpu_load": round(cycles / budget, 4), "slack_cycles": round(budget - cycles),
            "slack_us": round((budget - cycles) / F_CPU_HZ * 1e6, 2)}


COMP_BANK_BUDGET = 850     # instructions of the compensator bank's phase in the worst tick (docs/firmware.md)


def comp_bank_phase(kernels: dict[str, dict]) -> dict[str, dict]:
    """The compensator bank's phase in every feedback configuration, worst over the ticks.

    Parameters
    ----------
    kernels : dict[str, dict]
        ``phase_cost.json`` kernels; a kernel measured per tick carries ``ticks``
        (phase -> Cortex-M4 instructions of every tick of the schedule).

    Returns
    -------
    dict[str, dict]
        Per kernel with the bank on (control_step_full / semi / dual):
        ``worst_instructions``, ``tick_instructions`` and ``within_budget``
        (``COMP_BANK_BUDGET``).
    """
    out: dict[str, dict] = {}
    for name in ("control_step_full", "control_step_semi", "control_step_dual"):
        ticks = kernels.get(name, {}).get("ticks", {}).get("comp_bank")
        if ticks:
            worst = max(ticks)
            out[name] = {"worst_instructions": worst, "tick_instructions": ticks,
                         "within_budget": worst <= COMP_BANK_BUDGET}
    return out


def with_online_estimator(kernels: dict, prefix: str = "isr_worst_case_fe_") -> dict | None:
    """Load of the worst period of one mode with the online Stribeck identification on.

    Parameters
    ----------
    kernels : dict
        ``cm4_cost.json`` ``kernels`` (name -> {"instructions": N}).  The kernels
        ``<prefix><kind>`` are the mode's worst tick (or its ticks folded into the worst,
        ``<prefix><kind>.s<k>`` being tick k) with fe_enable 1 and one kind of the
        estimator's work of the control period in the same period (its observation without
        and with a sample, the fed FF config's refresh, a period between them); the sample
        and the fit are the background's (``background``).
    prefix : str
        The mode's kernel name followed by ``_fe_`` (default: the full-closed PTP period).

    Returns
    -------
    dict or None
        ``instructions`` and ``worst_part`` (the worst of the parts), ``parts_instructions``,
        ``cpu_load`` (fraction of the 10 kHz period at 1.3 cycles per instruction plus the
        allowances) and ``within_target``; None without those kernels.
    """
    parts = {k[len(prefix):]: int(v["instructions"]) for k, v in kernels.items()
             if k.startswith(prefix) and "." not in k}
    if not parts:
        return None
    worst = max(parts, key=lambda p: parts[p])
    n = parts[worst]
    load = (n * CPI + sum(ALLOW_CYCLES.values())) / (F_CPU_HZ / F_CTRL_HZ)
    return {"instructions": n, "worst_part": worst, "parts_instructions": parts,
            "cpu_load": round(load, 4), "within_target": load <= TARGET}


#: the modes measured with the online estimator on (``<mode>_fe_<kind>`` kernels); the PTP
#: period without backstepping is a subset of ``isr_worst_case``'s work
FE_MODES = ("isr_worst_case", "isr_worst_case_exc", "isr_worst_case_semi_t2")


def estimator_modes(kernels: dict) -> dict[str, dict | None]:
    """The worst period of every mode of ``FE_MODES`` with the online estimator on.

    Parameters
    ----------
    kernels : dict
        ``cm4_cost.json`` ``kernels``.

    Returns
    -------
    dict[str, dict | None]
        Mode kernel name -> ``with_online_estimator`` of its ``<mode>_fe_`` kernels (None:
        not measured).
    """
    return {m: with_online_estimator(kernels, m + "_fe_") for m in FE_MODES}


def background(kernels: dict, fe_decim: int = 10) -> dict | None:
    """CPU taken by the online identification's background (below the control period).

    Parameters
    ----------
    kernels : dict
        ``cm4_cost.json`` ``kernels``; ``fe_background_step`` is the background's work of one
        estimator step at its longest (a sample of an established visit and the pass that
        closes a fit), Cortex-M4 instructions.
    fe_decim : int
        Control periods per estimator step (the default 10: 1 kHz).

    Returns
    -------
    dict or None
        ``step_instructions``, ``fe_decim``, ``cpu_load`` (fraction of the CPU at one such
        step every ``fe_decim`` periods, 1.3 cycles per instruction) and ``fits_beside_isr``
        (that load within what the worst control period leaves, 1 - ``TARGET``); None
        without the kernel.
    """
    if "fe_background_step" not in kernels:
        return None
    n = int(kernels["fe_background_step"]["instructions"])
    load = n * CPI / (fe_decim * F_CPU_HZ / F_CTRL_HZ)
    return {"step_instructions": n, "fe_decim": fe_decim, "cpu_load": round(load, 4),
            "fits_beside_isr": load <= 1.0 - TARGET}


#: the worst-case kernels per operating mode, each folded over the ticks of the schedule
MODES = {
    "isr_worst_case": "PTP, full closed, every compensator (backstepping on)",
    "isr_worst_case_pid": "PTP, full closed, every compensator but backstepping",
    "isr_worst_case_exc": "excitation (multisine of 4 lines on the held position), every compensator",
    "isr_worst_case_semi_t2": "PTP, semi-closed, every compensator and compliance, "
                              "twist torque from the motor side (pr_t_src 2)",
}


def modes(kernels: dict) -> dict:
    """The worst control period of every operating mode against the target.

    Parameters
    ----------
    kernels : dict
        ``cm4_cost.json`` "kernels": name -> {"instructions": N [instructions],
        optionally "worst_slot" and "slots" [instructions per tick]}.

    Returns
    -------
    dict
        Mode kernel name -> {"what", "instructions" [instructions], "worst_tick",
        "tick_instructions", "cycles" [cycles per 100 us period, with the allowance],
        "cpu_load" [fraction of the 10 kHz period], "within_target" (bool)}, for the
        kernels of ``MODES`` present.
    """
    budget = F_CPU_HZ / F_CTRL_HZ
    out = {}
    for name, what in MODES.items():
        if name not in kernels:
            continue
        n = int(kernels[name]["instructions"])
        cycles = n * CPI + sum(ALLOW_CYCLES.values())
        out[name] = {"what": what, "instructions": n,
                     "worst_tick": kernels[name].get("worst_slot"),
                     "tick_instructions": kernels[name].get("slots"),
                     "cycles": round(cycles), "cpu_load": round(cycles / budget, 4),
                     "within_target": cycles / budget <= TARGET}
    return out


def estimator_check(fe: dict[str, dict | None]) -> tuple[bool, str]:
    """The budget check of every mode's worst period with the online estimator on.

    Parameters
    ----------
    fe : dict[str, dict | None]
        ``estimator_modes``: mode -> ``with_online_estimator`` (None: the cost image has no
        estimator kernels of that mode).

    Returns
    -------
    tuple[bool, str]
        Whether the check passes and its one-line verdict (every mode's figure).  A mode
        without kernels fails (the figure must be measured, never assumed).
    """
    missing = [m for m, v in fe.items() if v is None]
    if not fe or missing:
        return False, (f"online estimator: no {', '.join(m + '_fe_*' for m in missing) or 'isr_worst_case_fe_*'} "
                       "kernels in cm4_cost.json (check FAILED)")
    over = [m for m, v in fe.items() if v is not None and not v["within_target"]]
    figs = "; ".join(f"{m} {v['instructions']} ({v['worst_part']}, {100 * v['cpu_load']:.1f} %)"
                     for m, v in fe.items() if v is not None)
    return not over, (f"online estimator, worst period per mode: {figs} against {100 * TARGET:.0f} %: "
                      + ("within" if not over else "check FAILED (" + ", ".join(over) + ")"))


def main() -> int:
    if not SRC.exists():
        print(f"{SRC.relative_to(ROOT)}: missing (run tests/bench/10_cm4_cost.sh first)")
        return 1
    k = json.loads(SRC.read_text())["kernels"]
    if "isr_worst_case" not in k:
        print(f"{SRC.relative_to(ROOT)}: no kernel 'isr_worst_case'")
        return 1
    insn = k["isr_worst_case"]["instructions"]
    parts = {n: k[n]["instructions"] for n in ("isr_worst_case_pid", "isr_worst_case_exc", "isr_worst_case_semi_t2",
                                               "control_step_full",
                                               "control_step_baseline",
                                               "foc_step", "ssi_decode", "enc_update")
             if n in k}
    cycles = insn * CPI + sum(ALLOW_CYCLES.values())
    budget = F_CPU_HZ / F_CTRL_HZ
    load = cycles / budget
    out = {
        "meta": {
            "source": "build/bench/cm4_cost.json and phase_cost.json (QEMU instruction counts)",
            "cpu_hz": F_CPU_HZ, "control_hz": F_CTRL_HZ, "pwm_foc_hz": F_PWM_HZ,
            "cycles_per_instruction_assumed": CPI,
            "assumption": "1.3 cycles/instruction average on the Cortex-M4 at 170 MHz with 4 flash wait "
                          "states hidden by the ART accelerator; allowances in cycles for work the "
                          "emulator does not run",
            "target_load": TARGET,
        },
        "isr_worst_case_instructions": insn,
        "parts_instructions": parts,
        "allowance_cycles": ALLOW_CYCLES,
        "cycles_per_control_period": round(cycles),
        "cycles_available": round(budget),
        "cpu_load": round(load, 4),
        "within_target": load <= TARGET,
    }
    out["modes"] = modes(k)
    fe_modes = estimator_modes(k)
    if fe_modes["isr_worst_case"] is not None:
        out["with_online_estimator"] = fe_modes["isr_worst_case"]
    out["with_online_estimator_modes"] = fe_modes
    bg = background(k)
    if bg is not None:
        out["online_estimator_background"] = bg
    if "slots" in k["isr_worst_case"]:
        # the bank's schedule (firmware/app/hd_sched.h): every tick of one cycle, the worst counts
        sl = k["isr_worst_case"]["slots"]
        out["schedule"] = {"ticks_per_cycle": len(sl), "worst_tick": k["isr_worst_case"]["worst_slot"],
                           "tick_instructions": sl,
                           "tick_cpu_load": [round((n * CPI + sum(ALLOW_CYCLES.values())) / budget, 4) for n in sl]}
    if PHASES_SRC.exists() and "ssi_decode" in k:
        ph = json.loads(PHASES_SRC.read_text())["kernels"].get("isr_worst_case", {}).get("phases_instructions")
        if ph:
            port = ph["before_step"]
            step = insn - port
            per_foc = (port - k["ssi_decode"]["instructions"]) / 2
            out["phases_instructions"] = {"port (2 FOC periods + frame decode)": port,
                                          **{n: v for n, v in ph.items() if n not in ("before_step", "after_step")}}
            out["slack"] = {"10kHz": slack(step, per_foc, k["ssi_decode"]["instructions"], 10e3),
                            "20kHz": slack(step, per_foc, k["ssi_decode"]["instructions"], 20e3)}
        out["comp_bank_phase"] = comp_bank_phase(json.loads(PHASES_SRC.read_text())["kernels"])
    DST.write_text(json.dumps(out, indent=2) + "\n")
    print(f"isr_worst_case: {insn} instructions x {CPI} + {sum(ALLOW_CYCLES.values())} cycles allowance "
          f"= {cycles:.0f} of {budget:.0f} cycles per 100 us -> CPU load {100 * load:.1f} % "
          f"(target <= {100 * TARGET:.0f} %: {'met' if load <= TARGET else 'NOT met'})")
    for n, v in parts.items():
        print(f"  {n:24s} {v:6d} instructions ({100 * v * CPI / budget:.1f} %)")
    for n, v in out["modes"].items():
        print(f"  mode {n:24s} {v['instructions']:6d} instructions, load {100 * v['cpu_load']:.1f} % "
              f"({'met' if v['within_target'] else 'NOT met'}): {v['what']}")
    for n, fe in out["with_online_estimator_modes"].items():
        if fe is not None:
            print(f"  mode {n} with the online estimator's worst part ({fe['worst_part']}): "
                  f"{fe['instructions']} instructions, load {100 * fe['cpu_load']:.1f} % "
                  f"({'met' if fe['within_target'] else 'NOT met'})")
    if "online_estimator_background" in out:
        bg = out["online_estimator_background"]
        print(f"  online estimator's background: {bg['step_instructions']} instructions per step at its longest, "
              f"{100 * bg['cpu_load']:.1f} % of the CPU at fe_decim {bg['fe_decim']} (below the control period)")
    if "schedule" in out:
        sc = out["schedule"]
        print(f"  schedule: {sc['ticks_per_cycle']} ticks per cycle, worst tick {sc['worst_tick']}: "
              + ", ".join(str(n) for n in sc["tick_instructions"]))
    for n, v in out.get("phases_instructions", {}).items():
        print(f"  phase {n:36s} {v:6d} instructions")
    for n, v in out.get("comp_bank_phase", {}).items():
        print(f"  comp_bank phase, {n:24s} worst tick {v['worst_instructions']:5d} instructions "
              f"(budget {COMP_BANK_BUDGET}): " + ", ".join(str(t) for t in v["tick_instructions"]))
    for n, v in out.get("slack", {}).items():
        print(f"  at {n}: load {100 * v['cpu_load']:.1f} %, slack {v['slack_cycles']} cycles ({v['slack_us']} us)")
    print(f"wrote {DST.relative_to(ROOT)}")
    ok, verdict = estimator_check(out["with_online_estimator_modes"])
    print(verdict)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
