#!/usr/bin/env python3
"""Runs the test suite on lavapipe as a GPU that fuses multiply-adds would: every f32
GLSL.std.450 `Fma` in spirv/ computed exactly and rounded once.

Why: the SPIR-V shaderc writes already holds `Fma` for an unmarked a * b + c (as
glsl/checks/contraction.comp shows) and for every fma(); lavapipe evaluates it as a rounded
product and a rounded sum, an NVIDIA GPU as one fused operation, and code whose result hangs on
that difference passes every twin test here and fails on the GPU — as essm's box mean did on an H200 (README, "Four-lane
subgroups and fused arithmetic"). `precise` code has no `Fma` (NoContraction), so this changes
nothing that says it must not be fused.

How: each module is disassembled (spirv-dis), each f32 (scalar or vector) `Fma` a b c replaced
by f64 arithmetic — the product of two floats is exact in f64, the sum rounded once to f64 and
then to f32 (a double rounding, which differs from a true fused result only where the f64 sum
falls exactly on an f32 rounding midpoint) — and reassembled with the same ids (spirv-as
--preserve-numeric-ids) and validated (spirv-val). The modules are rewritten in place, the
tests run, and spirv/ is put back from a copy taken first, whatever happens.

    python3 tools/fused_fma.py                  # the whole suite but the check that spirv/ is
                                                # what the GLSL compiles to (nextest where it
                                                # is installed, else cargo test: tools/test.sh)
    python3 tools/fused_fma.py --test essm      # cargo nextest run's own arguments
    python3 tools/fused_fma.py --rewrite-only   # leave the rewritten modules in place
                                                # (restore: git checkout spirv/; refused
                                                # unless spirv/ is as committed)
"""
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
SPIRV = ROOT / "spirv"


def run(*args, **kw):
    return subprocess.run(args, check=True, text=True, capture_output=True, **kw).stdout


def rewrite(text):
    """The module's assembly with every f32 Fma computed in f64; (text, count)."""
    lines = text.splitlines()
    bound = int(re.search(r"^; Bound: (\d+)", text, re.M).group(1))
    next_id = [bound]

    def fresh():
        next_id[0] += 1
        return f"%{next_id[0] - 1}"

    glsl = None
    f32 = f64 = None
    vec32 = {}  # id -> width
    vec64 = {}  # width -> id
    for line in lines:
        m = re.match(r"\s*(%\d+) = OpExtInstImport \"GLSL.std.450\"", line)
        if m:
            glsl = m.group(1)
        m = re.match(r"\s*(%\d+) = OpTypeFloat (\d+)$", line)
        if m:
            if m.group(2) == "32":
                f32 = m.group(1)
            elif m.group(2) == "64":
                f64 = m.group(1)
    if glsl is None or f32 is None:
        return text, 0
    for line in lines:
        m = re.match(r"\s*(%\d+) = OpTypeVector (%\d+) (\d+)$", line)
        if m and m.group(2) == f32:
            vec32[m.group(1)] = int(m.group(3))
        if m and f64 is not None and m.group(2) == f64:
            vec64[int(m.group(3))] = m.group(1)

    fma = re.compile(r"^(\s*)(%\d+) = OpExtInst (%\d+) " + re.escape(glsl) + r" Fma (%\d+) (%\d+) (%\d+)$")
    uses = [fma.match(line) for line in lines]
    widths = {vec32[m.group(3)] for m in uses if m and m.group(3) in vec32}
    if not any(m and (m.group(3) == f32 or m.group(3) in vec32) for m in uses):
        return text, 0

    new_types = []
    if f64 is None:
        f64 = fresh()
        new_types.append(f"{f64} = OpTypeFloat 64")
    for w in sorted(widths):
        if w not in vec64:
            vec64[w] = fresh()
            new_types.append(f"{vec64[w]} = OpTypeVector {f64} {w}")

    out = []
    count = 0
    decorations = []
    for line, m in zip(lines, uses):
        if m and (m.group(3) == f32 or m.group(3) in vec32):
            pad, r, ty, a, b, c = m.groups()
            t64 = f64 if ty == f32 else vec64[vec32[ty]]
            a64, b64, c64, p64, s64 = (fresh() for _ in range(5))
            out += [
                f"{pad}{a64} = OpFConvert {t64} {a}",
                f"{pad}{b64} = OpFConvert {t64} {b}",
                f"{pad}{c64} = OpFConvert {t64} {c}",
                f"{pad}{p64} = OpFMul {t64} {a64} {b64}",
                f"{pad}{s64} = OpFAdd {t64} {p64} {c64}",
                f"{pad}{r} = OpFConvert {ty} {s64}",
            ]
            decorations += [f"OpDecorate {p64} NoContraction", f"OpDecorate {s64} NoContraction"]
            count += 1
            continue
        out.append(line)
        if re.match(r"\s*" + re.escape(f32) + r" = OpTypeFloat 32$", line):
            out += new_types
    if not any(re.match(r"\s*OpCapability Float64$", line) for line in out):
        at = next(i for i, line in enumerate(out) if "OpCapability" in line)
        out.insert(at + 1, "OpCapability Float64")
    # Decorations go before the first type declaration (the annotation section's end).
    at = next(i for i, line in enumerate(out) if re.match(r"\s*%\d+ = OpType", line))
    out[at:at] = decorations
    return "\n".join(out) + "\n", count


def target_env(text):
    version = re.search(r"^; Version: (\d+)\.(\d+)", text, re.M).groups()
    return "spv{}.{}".format(*version)


def rewrite_all():
    total = modules = 0
    with tempfile.TemporaryDirectory() as tmp:
        for spv in sorted(SPIRV.rglob("*.spv")):
            text = run("spirv-dis", "--raw-id", "--no-color", str(spv))
            new, count = rewrite(text)
            if count == 0:
                continue
            asm = pathlib.Path(tmp) / "m.spvasm"
            asm.write_text(new)
            env = target_env(text)
            run("spirv-as", "--preserve-numeric-ids", "--target-env", env, "-o", str(spv), str(asm))
            run("spirv-val", "--target-env", "vulkan1.2" if env <= "spv1.5" else "vulkan1.3", str(spv))
            total += count
            modules += 1
    print(f"fused_fma: {total} Fma in {modules} modules now computed once rounded", flush=True)


def main():
    args = sys.argv[1:]
    if args == ["--rewrite-only"]:
        clean = subprocess.run(["git", "diff", "--quiet", "--", "spirv"], cwd=ROOT)
        if clean.returncode != 0:
            sys.exit("fused_fma: spirv/ has changes; commit them first (git restores it after)")
        rewrite_all()
        return
    backup = tempfile.TemporaryDirectory()
    saved = pathlib.Path(backup.name) / "spirv"
    shutil.copytree(SPIRV, saved)
    try:
        rewrite_all()
        stale = "committed_spirv_is_up_to_date"
        if args:
            cmd = ["cargo", "nextest", "run", "--no-fail-fast"] + args
        elif shutil.which("cargo-nextest"):
            cmd = ["cargo", "nextest", "run", "--no-fail-fast", "--features", "shader-compiler",
                   "-E", f"not test(={stale})"]
        else:
            cmd = ["cargo", "test", "--no-fail-fast", "--features", "shader-compiler", "--",
                   "--skip", stale]
        rc = subprocess.run(cmd, cwd=ROOT).returncode
    finally:
        # Copied back, not checked out: a change to the shaders not yet committed stays. With
        # fresh times (shutil.copy, not copy2): cargo rebuilds what embeds them only if they
        # are newer than its last build, which embedded the rewritten ones.
        shutil.rmtree(SPIRV)
        shutil.copytree(saved, SPIRV, copy_function=shutil.copy)
        backup.cleanup()
        print("fused_fma: spirv/ restored", flush=True)
    sys.exit(rc)


if __name__ == "__main__":
    main()
