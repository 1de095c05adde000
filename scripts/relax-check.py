#!/usr/bin/env python3
"""Checks that linker relaxation changed nothing but the calls and jumps it may change.

The firmwares link with `-Wl,--relax` (.cargo/config.toml): avr-ld turns a `call`/`jmp` whose
target is within ±4 KB into a 2-byte `rcall`/`rjmp`, a `call` + `ret` into a tail jump, and
drops the alignment padding that no longer lines up. LLVM-AVR has had relaxation bugs (a
relative branch resolved by the assembler would point off by the deleted bytes), so this
script compares a relaxed ELF with the same firmware linked without `--relax`, instruction by
instruction:

* every instruction is byte-identical, except
* `call`/`jmp` ↔ `rcall`/`rjmp` (or a `call`; `ret` pair ↔ a tail `rjmp`/`jmp`) to the same
  instruction, and every relative branch to the same instruction (targets mapped through the
  pairing);
* `nop` padding the relaxed one dropped;
* `__do_copy_data`'s load of `__data_load_start` (the .data image moved with the shorter text);
* `.data` byte-identical.

Usage: relax-check.py UNRELAXED.elf RELAXED.elf  (exit status 1 on any other difference).
`scripts/relax-check` builds the three node firmwares both ways and runs it on each.
"""
import re
import subprocess
import sys

BRANCH = re.compile(r"^(rjmp|rcall|br\w+)$")
LINE = re.compile(r"\s+([0-9a-f]+):\t((?:[0-9a-f]{2} )+)\s*\t?(\S*)\s*(.*)")


def disassemble(elf):
    """(section, address, raw bytes, mnemonic, operands) of every instruction."""
    out = subprocess.run(
        ["avr-objdump", "-d", "-z", elf], capture_output=True, text=True, check=True
    ).stdout
    ins, sec = [], None
    for line in out.splitlines():
        m = re.match(r"Disassembly of section (\S+):", line)
        if m:
            sec = m.group(1)
            continue
        m = LINE.match(line)
        if m:
            ops = m.group(4).split(";")[0].strip()
            ins.append((sec, int(m.group(1), 16), m.group(2).strip(), m.group(3), ops))
    return ins


def symbols(elf):
    out = subprocess.run(["avr-nm", elf], capture_output=True, text=True, check=True).stdout
    return {p[2]: int(p[0], 16) for p in (l.split() for l in out.splitlines()) if len(p) == 3}


def flash_objects(elf):
    """Address ranges of the data objects in flash (progmem tables): their bytes may decode as
    branches, which are not code to map."""
    out = subprocess.run(["avr-readelf", "-sW", elf], capture_output=True, text=True, check=True).stdout
    ranges = []
    for line in out.splitlines():
        p = line.split()
        if len(p) >= 8 and p[3] == "OBJECT" and p[2].isdigit():
            start, size = int(p[1], 16), int(p[2])
            if start < 0x800000 and size > 0:
                ranges.append((start, start + size))
    return ranges


def section(elf, name):
    out = subprocess.run(
        ["avr-objcopy", "-O", "binary", "-j", name, elf, "/dev/stdout"],
        capture_output=True,
        check=True,
    ).stdout
    return out


def target(ins):
    """The address a call, jump or branch goes to, else None."""
    _, addr, _, mn, ops = ins
    if mn in ("call", "jmp"):
        return int(ops, 16)
    if BRANCH.match(mn):
        m = re.search(r"\.([+-]\d+)", ops)
        if m:
            return addr + 2 + int(m.group(1))
    return None


def check(unrelaxed, relaxed):
    a, b = disassemble(unrelaxed), disassemble(relaxed)
    sa, sb = symbols(unrelaxed), symbols(relaxed)
    amap, pairs, tail_calls, dropped = {}, [], set(), 0
    i = j = 0
    while i < len(a) and j < len(b):
        x, y = a[i], b[j]
        amap[x[1]] = y[1]
        if x[3] == "nop" and y[3] != "nop":
            dropped += 1
            i += 1
            continue
        pairs.append((x, y))
        if x[3] == "jmp" and y[3] == "rjmp" and j + 1 < len(b) and b[j + 1][3] == "nop":
            j += 1  # a vector slot keeps its 4 bytes: rjmp + nop
        if x[3] == "call" and y[3] in ("rjmp", "jmp"):
            tail_calls.add(x[1])
            if i + 1 < len(a) and a[i + 1][3] == "ret" and not (j + 1 < len(b) and b[j + 1][3] == "ret"):
                i += 1
                amap[a[i][1]] = y[1]
        i += 1
        j += 1
    problems = []
    if i != len(a) or j != len(b):
        problems.append(f"unpaired instructions at the end: {len(a) - i} / {len(b) - j}")
    copy = sa.get("__do_copy_data")
    data = flash_objects(unrelaxed)
    relaxed_count = 0
    for x, y in pairs:
        if any(lo <= x[1] < hi for lo, hi in data):
            # A table in flash: its bytes must be the same, whatever they decode as.
            if x[2] != y[2]:
                problems.append(f"table bytes {x} | {y}")
            continue
        tx, ty = target(x), target(y)
        if tx is None and x[2] == y[2]:
            continue
        if tx is not None and ty is not None:
            kinds = {x[3], y[3]}
            same_kind = (
                x[3] == y[3]
                or kinds in ({"call", "rcall"}, {"jmp", "rjmp"})
                or (x[3] == "call" and y[3] in ("rjmp", "jmp") and x[1] in tail_calls)
            )
            if same_kind and amap.get(tx) == ty:
                relaxed_count += x[3] != y[3]
                continue
        # The .data image's address in flash, loaded into Z by __do_copy_data.
        if copy is not None and copy <= x[1] < copy + 16 and x[3] == y[3] == "ldi":
            reg, val = y[4].split(",")
            want = sb["__data_load_start"]
            if (reg.strip() == "r30" and int(val, 16) == want & 0xFF) or (
                reg.strip() == "r31" and int(val, 16) == want >> 8
            ):
                continue
        problems.append(f"{x} | {y}")
    if section(unrelaxed, ".data") != section(relaxed, ".data"):
        problems.append(".data differs")
    saved = len(section(unrelaxed, ".text")) - len(section(relaxed, ".text"))
    print(
        f"{relaxed}: {len(a)} instructions, {relaxed_count} calls/jumps relaxed, "
        f"{dropped} padding nops dropped, {saved} B less text, {len(problems)} differences"
    )
    for p in problems[:20]:
        print("  DIFFERENCE", p)
    return not problems


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(0 if check(sys.argv[1], sys.argv[2]) else 1)
