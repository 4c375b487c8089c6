#!/usr/bin/env python3
"""Instruction count of one control tick (`dca_core::controller::Controller::step`).

Builds the `dca-count` binary (firmware/count/main.rs) for thumbv7em-none-eabihf with
the board's profile (`firmware`, opt-level "s", LTO), loads its PT_LOAD segments into
the unicorn engine (Cortex-M4 with FPU) and calls `count_step` once per 1 kHz tick.
Counted per call of `count_step` (`Controller::step` plus building its `Sample`, a few
instructions). The numbers are executed *instructions*, not cycles (the Cortex-M4 needs more than one
cycle for loads, stores, branches, divisions and double-word multiplies; flash wait
states add more).

Counting: a basic-block hook adds the number of Thumb instructions of every block that
runs (a halfword whose top five bits are 0b11101, 0b11110 or 0b11111 starts a 32-bit
instruction). Instructions skipped inside an IT block are counted (the core issues
them); `--exact` uses a per-instruction hook instead, which skips them, as a
cross-check.

Input sequences (closed loop with a small plant model, deterministic):
  step    reference 0 -> 50 mm at t = 0, load steps at 4 s and 7 s, 10 s
          (host-sim's `stepload` scenario)
  sine    r = 20 mm (1 - cos 2 pi 0.5 t) + 10 mm, 6 s
  stress  Xo and the reference uniformly random over the sensor range (+-20 mm
          beyond it for the reference), 30 s: the ESO far outside its linear zone,
          every clamp, every fal branch; only for the worst case
The typical tick is the median over `step` and `sine`; the worst is the largest over
all three. `--log FILE` replays a host-sim run log (its xo_m and ref_m columns, one
row per 1 ms) instead of the closed loop.

The ESO's exp2 is the one loop whose length depends on the data (one multiply per set
fraction bit); the script also reports the worst MPC-ESO tick with both exp2 calls at
all 24 bits set (the bound), and gates on the larger of the two.

The constrained MPC-ESO (`cmpc-eso`, preset `limit`) solves its quadratic program by
evaluating all 27 active-bound patterns on every MPC tick, a loop of fixed length: its
worst tick is the same bound with the ESO's exp2 at its maximum.

The on-board record's part of a tick (`Recorder::push` through `count_record_push`, a
64-row record in two blocks filled three times with random inputs over and beyond every
range) is counted too and added to the worst ticks: the record running.

Exit status 1 when the worst MPC-ESO tick (or that bound) exceeds `--max-mpc-eso`
(default 2000), or the worst constrained MPC-ESO tick (or its bound) exceeds
`--max-cmpc-eso` (default 5000), without or with the record running.
"""

import argparse
import csv
import math
import os
import random
import shutil
import statistics
import struct
import subprocess
import sys

try:
    from elftools.elf.elffile import ELFFile
    from elftools.elf.sections import SymbolTableSection
    from unicorn import UC_ARCH_ARM, UC_HOOK_BLOCK, UC_HOOK_CODE, UC_MODE_MCLASS, UC_MODE_THUMB, Uc
    from unicorn.arm_const import (
        UC_ARM_REG_LR,
        UC_ARM_REG_R0,
        UC_ARM_REG_R1,
        UC_ARM_REG_S0,
        UC_ARM_REG_S1,
        UC_ARM_REG_SP,
        UC_CPU_ARM_CORTEX_M4,
    )
except ImportError:
    sys.exit("count.py needs the unicorn engine and pyelftools: pip install unicorn pyelftools")

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
TARGET = "thumbv7em-none-eabihf"
DEFAULT_ELF = os.path.join(ROOT, "target", TARGET, "firmware", "dca-count")
BUILD = [
    "cargo", "build", "-p", "dca-firmware", "--profile", "firmware", "--target", TARGET,
    "--features", "count", "--bin", "dca-count",
]

# Kind indices of count_init (ControllerKind::ALL) and their names.
KINDS = [("mpc-eso", 0), ("mpc", 1), ("pid", 2), ("fuzzy-pid", 3), ("cmpc-eso", 4)]
# Controllers with the ESO (its exp2 is the data-dependent loop; see eso_bound).
ESO_KINDS = ("mpc-eso", "cmpc-eso")

FLASH, FLASH_SIZE = 0x0800_0000, 0x0008_0000
RAM, RAM_SIZE = 0x2000_0000, 0x0002_0000
SLOT = RAM  # the Controller (8-aligned)
STACK_TOP = RAM + RAM_SIZE
TRAP = 0x0900_0000  # return address: emulation stops here

DT_S = 1.0e-3  # board tick
LVDT_LSB_M = 0.12 / 4096  # the board's 12-bit LVDT channel, -10 ... 110 mm


def f32(x):
    return struct.unpack("<f", struct.pack("<f", x))[0]


def f32_bits(x):
    return struct.unpack("<I", struct.pack("<f", x))[0]


def bits_f32(b):
    return struct.unpack("<f", struct.pack("<I", b & 0xFFFF_FFFF))[0]


class Target:
    """The dca-count ELF in unicorn, with a per-call instruction counter."""

    def __init__(self, elf_path, exact=False, profile=False):
        self.uc = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        self.uc.ctl_set_cpu_model(UC_CPU_ARM_CORTEX_M4)
        self.uc.mem_map(FLASH, FLASH_SIZE)
        self.uc.mem_map(RAM, RAM_SIZE)
        self.uc.mem_map(TRAP, 0x1000)
        self.symbols = {}
        self.funcs = []  # (start, end, name) of FUNC symbols, for --profile
        with open(elf_path, "rb") as fh:
            elf = ELFFile(fh)
            for seg in elf.iter_segments():
                if seg["p_type"] == "PT_LOAD" and seg["p_filesz"] > 0:
                    self.uc.mem_write(seg["p_vaddr"], seg.data())
            for sec in elf.iter_sections():
                if isinstance(sec, SymbolTableSection):
                    for s in sec.iter_symbols():
                        if s["st_info"]["type"] == "STT_FUNC" and s["st_size"] > 0:
                            a = s["st_value"] & ~1
                            self.symbols[s.name] = a
                            self.funcs.append((a, a + s["st_size"], s.name))
        self.funcs.sort()
        self.count = 0
        self.per_func = {} if profile else None
        self.blocks = {}
        if exact:
            self.uc.hook_add(UC_HOOK_CODE, self._on_insn)
        else:
            self.uc.hook_add(UC_HOOK_BLOCK, self._on_block)

    def _insns(self, addr, size):
        key = (addr, size)
        n = self.blocks.get(key)
        if n is None:
            code = self.uc.mem_read(addr, size)
            n, i = 0, 0
            while i < size:
                hw = code[i] | code[i + 1] << 8
                i += 4 if (hw >> 11) in (0b11101, 0b11110, 0b11111) else 2
                n += 1
            self.blocks[key] = n
        return n

    def _func(self, addr):
        lo, hi = 0, len(self.funcs)
        while lo < hi:
            mid = (lo + hi) // 2
            if self.funcs[mid][0] <= addr:
                lo = mid + 1
            else:
                hi = mid
        if lo and addr < self.funcs[lo - 1][1]:
            return self.funcs[lo - 1][2]
        return "?"

    def _attribute(self, addr, n):
        if self.per_func is not None:
            name = self._func(addr)
            self.per_func[name] = self.per_func.get(name, 0) + n

    def _on_block(self, uc, addr, size, _):
        n = self._insns(addr, size)
        self.count += n
        self._attribute(addr, n)

    def _on_insn(self, uc, addr, size, _):
        self.count += 1
        self._attribute(addr, 1)

    def call(self, name, r=(), s=()):
        """Call `name` with integer args `r` and f32 args `s`; returns (r0, s0, count)."""
        for reg, v in zip((UC_ARM_REG_R0, UC_ARM_REG_R1), r):
            self.uc.reg_write(reg, v)
        for reg, v in zip((UC_ARM_REG_S0, UC_ARM_REG_S1), s):
            self.uc.reg_write(reg, f32_bits(v))
        self.uc.reg_write(UC_ARM_REG_SP, STACK_TOP)
        self.uc.reg_write(UC_ARM_REG_LR, TRAP | 1)
        self.count = 0
        self.uc.emu_start(self.symbols[name] | 1, TRAP)
        return self.uc.reg_read(UC_ARM_REG_R0), bits_f32(self.uc.reg_read(UC_ARM_REG_S0)), self.count


class Plant:
    """Ball screw (Xi integrates the command) and a hydraulic link Xo <- Xi
    (second order, 6 Hz, damping 0.5), a load that compresses the link by `sag_m`,
    and the LVDT's 12-bit quantisation. Enough to give each controller its own
    realistic transient; not the paper's plant (host-sim has that)."""

    def __init__(self):
        self.xi = self.xo = self.vo = 0.0
        self.sag_m = 0.0

    def measure(self):
        return f32(round(self.xo / LVDT_LSB_M) * LVDT_LSB_M)

    def advance(self, v_mps):
        w, z = 2 * math.pi * 6.0, 0.5
        sub = 10
        h = DT_S / sub
        for _ in range(sub):
            self.xi = min(max(self.xi + v_mps * h, -0.010), 0.110)
            acc = w * w * (self.xi - self.sag_m - self.xo) - 2 * z * w * self.vo
            self.vo += acc * h
            self.xo += self.vo * h


def scenario(name):
    """(reference(t), load sag(t), ticks) of a closed-loop scenario."""
    if name == "step":
        return (lambda t: 0.05), (lambda t: 0.002 * (t >= 4.0) - 0.001 * (t >= 7.0)), 10_000
    if name == "sine":
        return (lambda t: 0.01 + 0.02 * (1 - math.cos(2 * math.pi * 0.5 * t))), (lambda t: 0.0), 6_000
    raise ValueError(name)


def run_closed_loop(tgt, name):
    """Counts and the (xo, ref) inputs of one closed-loop scenario."""
    ref, sag, n = scenario(name)
    plant = Plant()
    counts, inputs = [], []
    for k in range(n):
        t = k * DT_S
        plant.sag_m = sag(t)
        xo, r = plant.measure(), f32(ref(t))
        _, v, c = tgt.call("count_step", r=(SLOT,), s=(xo, r))
        counts.append(c)
        inputs.append((xo, r))
        plant.advance(v)
    return counts, inputs


def stress_inputs(n=30_000, seed=1):
    rnd = random.Random(seed)
    return [(f32(rnd.uniform(-0.010, 0.110)), f32(rnd.uniform(-0.030, 0.130))) for _ in range(n)]


def log_inputs(path):
    with open(path) as fh:
        lines = [line for line in fh if not line.startswith("#")]
    return [(f32(float(row["xo_m"])), f32(float(row["ref_m"]))) for row in csv.DictReader(lines)]


def replay(tgt, inputs):
    return [tgt.call("count_step", r=(SLOT,), s=(xo, r))[2] for xo, r in inputs]


def init(tgt, kind_index):
    """Design controller `kind_index` into the slot; returns (size in bytes, n_h, n_c)."""
    size = tgt.call("count_controller_size")[0]
    if tgt.call("count_init", r=(kind_index, SLOT))[0] != 1:
        sys.exit(f"count_init({kind_index}) refused the design")
    tgt.call("count_periods", r=(SLOT,))
    n_h, n_c = tgt.uc.reg_read(UC_ARM_REG_R0), tgt.uc.reg_read(UC_ARM_REG_R1)
    return size, n_h, n_c


def count_kind(args, idx):
    """({sequence: (counts, inputs)}, n_h, n_c) for one controller, each sequence
    from a fresh design."""
    tgt = Target(args.elf, exact=args.exact)
    out = {}
    if args.log:
        inputs = log_inputs(args.log)
        _, n_h, n_c = init(tgt, idx)
        out["log"] = (replay(tgt, inputs), inputs)
        return out, n_h, n_c
    for sc in ("step", "sine"):
        _, n_h, n_c = init(tgt, idx)
        out[sc] = run_closed_loop(tgt, sc)
    inputs = stress_inputs()
    init(tgt, idx)
    out["stress"] = (replay(tgt, inputs), inputs)
    return out, n_h, n_c


def profile_tick(args, idx, inputs, at):
    """Per-function instructions of tick `at` of `inputs` (replayed from a fresh design)."""
    tgt = Target(args.elf, exact=args.exact, profile=True)
    init(tgt, idx)
    tgt.per_func = None
    replay(tgt, inputs[:at])
    tgt.per_func = {}
    total = tgt.call("count_step", r=(SLOT,), s=inputs[at])[2]
    return total, sorted(tgt.per_func.items(), key=lambda kv: -kv[1]), tgt


def demangle(name):
    """Legacy Rust symbol (_ZN...E) to a path without the hash; others unchanged."""
    if not name.startswith("_ZN"):
        return name
    i, parts = 3, []
    while i < len(name) and name[i].isdigit():
        j = i
        while name[j].isdigit():
            j += 1
        n = int(name[i:j])
        parts.append(name[j : j + n])
        i = j + n
    if parts and parts[-1].startswith("h") and len(parts[-1]) == 17:
        parts.pop()
    path = "::".join(parts)
    for esc, ch in (("$LT$", "<"), ("$GT$", ">"), ("$C$", ","), ("$u20$", " "), ("..", "::")):
        path = path.replace(esc, ch)
    return path


# The one data-dependent loop of the MPC-ESO tick: exp2 of a fal power (Q8.24), one
# multiply per set bit of its 24 fraction bits. A fal power |e|^alpha with
# delta < |e| < 8 m has an integer part of log2 between -8 and 2.
EXP2_SYMBOL = "dca_core::fxp::exp2_to_pos"
EXP2_ALL_ONES = [(ip << 24) | 0xFF_FFFF for ip in range(-8, 3)]


def eso_bound(tgt, exp2_at_worst):
    """Instructions to add to the worst tick for both exp2 calls at 24 set bits (the
    data-dependent part at its maximum). None when exp2 has no symbol of its own."""
    names = {demangle(n): n for n in tgt.symbols}
    if EXP2_SYMBOL not in names or exp2_at_worst is None:
        return None
    tgt.per_func = None
    n = max(tgt.call(names[EXP2_SYMBOL], r=(v & 0xFFFF_FFFF,))[2] for v in EXP2_ALL_ONES)
    return 2 * n - exp2_at_worst


REC_SLOT = RAM + 0x8000  # the Recorder (8-aligned)
REC_ROWS = RAM + 0x9000  # its 64 rows of 16 bytes
_REC_COUNTS = []


def record_push_counts(args):
    """Instructions of every call of count_record_push over 3 fills of the record."""
    if _REC_COUNTS:
        return _REC_COUNTS
    tgt = Target(args.elf, exact=args.exact)
    tgt.call("count_record_init", r=(REC_SLOT, REC_ROWS))
    rng = random.Random(3)
    for k in range(3 * 64):
        if k and k % 64 == 0:
            tgt.call("count_record_rearm", r=(REC_SLOT,))
        xo = rng.uniform(-0.02, 0.13)
        ref = rng.uniform(-1.5, 1.5)
        _, _, n = tgt.call("count_record_push", r=(REC_SLOT,), s=(xo, ref))
        _REC_COUNTS.append(n)
    return _REC_COUNTS


def record_push_worst(args):
    return max(record_push_counts(args))


def rec_median(args):
    return int(statistics.median(record_push_counts(args)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--elf", default=DEFAULT_ELF, help="the dca-count ELF")
    ap.add_argument("--no-build", action="store_true", help="do not run cargo build first")
    ap.add_argument("--exact", action="store_true", help="per-instruction hook (slower)")
    ap.add_argument("--log", help="replay a host-sim run log instead of the closed loop")
    ap.add_argument("--kind", help="only this controller (mpc-eso, mpc, pid, fuzzy-pid, cmpc-eso)")
    ap.add_argument("--profile", action="store_true",
                    help="per-function instructions of each controller's worst tick")
    ap.add_argument("--max-mpc-eso", type=int, default=2000,
                    help="fail if the worst MPC-ESO tick exceeds this (0: no check)")
    ap.add_argument("--max-cmpc-eso", type=int, default=5000,
                    help="fail if the worst constrained MPC-ESO tick exceeds this (0: no check)")
    args = ap.parse_args()

    if not args.no_build:
        if shutil.which("cargo") is None:
            sys.exit("cargo not found")
        subprocess.run(BUILD, cwd=ROOT, check=True)

    print("Executed instructions (not cycles) per call of Controller::step:")
    print('thumbv7em-none-eabihf, profile `firmware` (opt-level "s", LTO), paper preset')
    print("(cmpc-eso: limit) at the 1 kHz board tick, unicorn engine ("
          + ("per-instruction hook" if args.exact else "block hook") + ").")
    print()
    rows = []
    eso_worst = {}  # ESO kind -> (worst tick, bound or None, note)
    for name, idx in KINDS:
        if args.kind and name != args.kind:
            continue
        runs, n_h, n_c = count_kind(args, idx)
        typical = [(c, k) for sc, (counts, _) in runs.items() if sc != "stress"
                   for k, c in enumerate(counts)]
        update = [c for c, k in typical if k % n_c == 0]
        every = [(c, sc, k) for sc, (counts, _) in runs.items() for k, c in enumerate(counts)]
        worst, worst_sc, worst_k = max(every)
        rows.append((name, n_h, n_c, int(statistics.median(c for c, _ in typical)),
                     int(statistics.median(update)), max(c for c, _ in typical), worst,
                     f"{worst_sc} k={worst_k}"))
        if args.profile or name in ESO_KINDS:
            total, funcs, tgt = profile_tick(args, idx, runs[worst_sc][1], worst_k)
            exp2 = {demangle(f): n for f, n in funcs}.get(EXP2_SYMBOL)
            if name in ESO_KINDS:
                extra = eso_bound(tgt, exp2)
                bound = None if extra is None else worst + extra
                note = (None if bound is None else
                        f"{name} bound: the worst tick with both exp2 at 24 set bits "
                        f"(instead of {exp2} instructions there) = {bound}")
                eso_worst[name] = (worst, bound, note)
            if args.profile:
                print(f"{name}: worst tick ({worst_sc} k={worst_k}): {total} instructions")
                for fn, n in funcs:
                    print(f"  {n:6d}  {demangle(fn)}")
                print()

    seq = "log" if args.log else "step + sine"
    print(f"| controller | n_h / n_c | typical tick (median, {seq}) "
          f"| update tick (median, k mod n_c = 0) | worst, {seq} | worst, all | worst at |")
    print("|---|---|---:|---:|---:|---:|---|")
    for name, n_h, n_c, med, upd, worst_typ, worst, at in rows:
        print(f"| {name} | {n_h} / {n_c} | {med} | {upd} | {worst_typ} | {worst} | {at} |")
    print()
    # The on-board record's part of a tick (Recorder::push), worst over varied inputs
    # and the switch between its two blocks; added to the worst ticks below.
    rec = record_push_worst(args)
    print(f"record running: Recorder::push adds at most {rec} instructions a tick "
          f"(median {rec_median(args)})")
    status = 0
    for name, limit in (("mpc-eso", args.max_mpc_eso), ("cmpc-eso", args.max_cmpc_eso)):
        if name not in eso_worst:
            continue
        w, bound, note = eso_worst[name]
        if note:
            print(note)
        if limit:
            gate = max(w, bound or 0)
            if gate > limit:
                print(f"FAIL: worst {name} tick {gate} instructions > {limit}")
                status = 1
            else:
                print(f"worst {name} tick {gate} instructions <= {limit}: ok")
            with_rec = gate + rec
            pct = 100.0 * rec / gate
            if with_rec > limit:
                print(f"FAIL: worst {name} tick with the record running {with_rec} > {limit}")
                status = 1
            else:
                print(f"worst {name} tick with the record running {with_rec} instructions "
                      f"(+{pct:.1f} %) <= {limit}: ok")
    return status


if __name__ == "__main__":
    sys.exit(main())
