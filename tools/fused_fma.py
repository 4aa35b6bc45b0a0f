#!/usr/bin/env python3
"""Runs the test suite on lavapipe as a GPU that fuses multiply-adds would: every f32
GLSL.std.450 `Fma` in spirv/, and every f32 product with the sum or difference that takes it
where neither is NoContraction, computed exactly and rounded once.

Why: the SPIR-V shaderc writes already holds `Fma` for an unmarked a * b + c (as
glsl/checks/contraction.comp shows) and for every fma(); lavapipe evaluates it as a rounded
product and a rounded sum, an NVIDIA GPU as one fused operation, and code whose result hangs on
that difference passes every twin test here and fails on the GPU — as essm's box mean did on an
H200 (README, "Four-lane subgroups and fused arithmetic"). `precise` code has no `Fma`
(NoContraction), so this changes nothing that says it must not be fused. A GPU compiler may
also contract a product into a sum that takes it in another statement, which shaderc leaves as
OpFMul and OpFAdd/OpFSub: those pairs are fused too (OpFMul or OpVectorTimesScalar, then OpFAdd
or OpFSub on either side), unless `--fma-only`. And the built-ins whose arithmetic SPIR-V leaves
to the device — OpDot, OpMatrixTimesVector, Cross, Length, Normalize, FMix — are computed as a
GPU that fuses may, one rounded product and then a fused multiply-add per further term
(builtin_chain; which order a given GPU takes is its own), unless `--no-builtins` or
`--fma-only`: lavapipe rounds each product and sums a matrix-vector product from its last
column, so code that hangs on either passes here and not on a GPU (the page raster's vertex
transform did: glsl/include/transform.glsl).

How: each module is disassembled (spirv-dis), each f32 (scalar or vector) a b + c replaced by
f64 arithmetic — the product of two floats is exact in f64, the sum rounded once to f64 and
then to f32 (a double rounding, which differs from a true fused result only where the f64 sum
falls exactly on an f32 rounding midpoint) — and reassembled with the same ids (spirv-as
--preserve-numeric-ids) and validated (spirv-val). Every conversion back to f32 is marked
NoContraction too: unmarked, lavapipe's compiler folds a narrowing and the widening after it
into nothing, so a chain's or a nested fma's intermediate results were kept in f64 and rounded
once at its end (tests/rounding.rs's
dot_and_matrix_products_are_within_rounding_in_the_devices_order found it: a chained dot
matched none of the four orders). The modules are rewritten in place, the tests run, and spirv/ is put back from a
copy taken first, whatever happens.

    python3 tools/fused_fma.py                  # the whole suite but the check that spirv/ is
                                                # what the GLSL compiles to (nextest where it
                                                # is installed, else cargo test: tools/test.sh)
    python3 tools/fused_fma.py --test essm      # cargo nextest run's own arguments
    python3 tools/fused_fma.py --fma-only       # only what shaderc already wrote as Fma
    python3 tools/fused_fma.py --no-builtins    # Fma and the product-sum pairs, no chains
    python3 tools/fused_fma.py --reverse        # the chains from their last term (a GPU's
                                                # order is its own: code must hang on neither)
    python3 tools/fused_fma.py --rewrite-only   # leave the rewritten modules in place
                                                # (restore: git checkout spirv/; refused
                                                # unless spirv/ is as committed)
"""
import collections
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
SPIRV = ROOT / "spirv"
# The built-ins' names as the README counts them.
NAMES = {"OpDot": "dot", "OpMatrixTimesVector": "m * v", "Cross": "cross", "Length": "length",
         "Normalize": "normalize", "FMix": "mix"}


def run(*args, **kw):
    return subprocess.run(args, check=True, text=True, capture_output=True, **kw).stdout


def rewrite(text, contract=False, builtins=False, reverse=False):
    """The module's assembly with every f32 Fma computed in f64, with `contract` every f32
    product and the sum or difference that takes it, neither NoContraction, and with `builtins`
    the dot products, matrix-vector products, cross products, lengths, normalizations and mixes
    as a GPU's chains of fused multiply-adds (`builtin_chain`); (text, (sites, built-ins by
    kind))."""
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
        return text, (0, collections.Counter())
    for line in lines:
        m = re.match(r"\s*(%\d+) = OpTypeVector (%\d+) (\d+)$", line)
        if m and m.group(2) == f32:
            vec32[m.group(1)] = int(m.group(3))
        if m and f64 is not None and m.group(2) == f64:
            vec64[int(m.group(3))] = m.group(1)

    def is_f32(ty):
        return ty == f32 or ty in vec32

    # Each operation to compute fused: line index -> (result, type, mul op, x, y, c, how), for
    # x * y (OpFMul, or OpVectorTimesScalar with y a scalar) and how: "+" (x y + c), "-"
    # (x y - c) or "r" (c - x y).
    fused = {}
    kept = set(re.findall(r"OpDecorate (%\d+) NoContraction", text))
    fma = re.compile(r"^\s*(%\d+) = OpExtInst (%\d+) " + re.escape(glsl) + r" Fma (%\d+) (%\d+) (%\d+)$")
    for i, line in enumerate(lines):
        m = fma.match(line)
        if m and is_f32(m.group(2)):
            r, ty, a, b, c = m.groups()
            fused[i] = (r, ty, "OpFMul", a, b, c, "+")
    if contract:
        muls = {}
        for line in lines:
            m = re.match(r"\s*(%\d+) = (OpFMul|OpVectorTimesScalar) (%\d+) (%\d+) (%\d+)$", line)
            if m and is_f32(m.group(3)) and m.group(1) not in kept:
                muls[m.group(1)] = (m.group(2), m.group(3), m.group(4), m.group(5))
        for i, line in enumerate(lines):
            m = re.match(r"\s*(%\d+) = (OpFAdd|OpFSub) (%\d+) (%\d+) (%\d+)$", line)
            if not m or m.group(1) in kept or not is_f32(m.group(3)):
                continue
            r, op, ty, p, q = m.groups()
            for mul, c, how in ((p, q, "+" if op == "OpFAdd" else "-"),
                                (q, p, "+" if op == "OpFAdd" else "r")):
                if mul in muls and muls[mul][1] == ty:
                    kind, _, x, y = muls[mul]
                    fused[i] = (r, ty, kind, x, y, c, how)
                    break
    chains = {}  # line index -> (result, type, built-in, operands)
    if builtins:
        chains = builtin_sites(lines, kept, glsl, f32, vec32)
    if not fused and not chains:
        return text, (0, collections.Counter())
    widths = {vec32[f[1]] for f in fused.values() if f[1] in vec32}
    widths |= {vec32[c[1]] for c in chains.values() if c[1] in vec32}

    new_types = []
    if f64 is None:
        f64 = fresh()
        new_types.append(f"{f64} = OpTypeFloat 64")
    for w in sorted(widths):
        if w not in vec64:
            vec64[w] = fresh()
            new_types.append(f"{vec64[w]} = OpTypeVector {f64} {w}")

    out = []
    decorations = []
    types = Types(f32, f64, vec32, vec64, fresh)
    for i, line in enumerate(lines):
        if i in chains:
            pad = re.match(r"\s*", line).group(0)
            chain, exact = builtin_chain(types, glsl, *chains[i], reverse=reverse)
            out += [pad + step for step in chain]
            decorations += [f"OpDecorate {x} NoContraction" for x in exact]
            continue
        if i in fused:
            r, ty, kind, x, y, c, how = fused[i]
            pad = re.match(r"\s*", line).group(0)
            t64 = types.wide(ty)
            # OpVectorTimesScalar's y is a scalar.
            y64_type = f64 if kind == "OpVectorTimesScalar" else t64
            x64, y64, c64, p64, s64 = (fresh() for _ in range(5))
            total = {"+": f"OpFAdd {t64} {p64} {c64}", "-": f"OpFSub {t64} {p64} {c64}",
                     "r": f"OpFSub {t64} {c64} {p64}"}[how]
            out += [
                f"{pad}{x64} = OpFConvert {t64} {x}",
                f"{pad}{y64} = OpFConvert {y64_type} {y}",
                f"{pad}{c64} = OpFConvert {t64} {c}",
                f"{pad}{p64} = {kind} {t64} {x64} {y64}",
                f"{pad}{s64} = {total}",
                f"{pad}{r} = OpFConvert {ty} {s64}",
            ]
            decorations += [f"OpDecorate {x} NoContraction" for x in (p64, s64, r)]
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
    kinds = collections.Counter(c[2] for c in chains.values())
    return "\n".join(out) + "\n", (len(fused), kinds)


class Types:
    """The ids of a module's float types, and of its fresh ids."""

    def __init__(self, f32, f64, vec32, vec64, fresh):
        self.f32, self.f64, self.vec32, self.vec64, self.fresh = f32, f64, vec32, vec64, fresh

    def wide(self, ty):
        """The f64 type of the f32 type `ty` (scalar or vector)."""
        return self.f64 if ty == self.f32 else self.vec64[self.vec32[ty]]


def builtin_sites(lines, kept, glsl, f32, vec32):
    """The f32 built-ins that a GPU computes as multiply-adds, none in `kept` (NoContraction):
    line index -> (result, type, built-in, operands)."""
    types = {}  # value id -> its type id
    matrices = {}  # matrix type id -> its column count
    for line in lines:
        m = re.match(r"\s*(%\d+) = OpTypeMatrix (%\d+) (\d+)$", line)
        if m:
            matrices[m.group(1)] = int(m.group(3))
        m = re.match(r"\s*(%\d+) = Op(?!Type)\w+ (%\d+)", line)
        if m:
            types[m.group(1)] = m.group(2)
    sites = {}
    ext = re.compile(r"^\s*(%\d+) = OpExtInst (%\d+) " + re.escape(glsl)
                     + r" (Cross|Length|Normalize|FMix) ((?:%\d+ ?)+)$")
    for i, line in enumerate(lines):
        m = re.match(r"\s*(%\d+) = (OpDot|OpMatrixTimesVector) (%\d+) (%\d+) (%\d+)$", line)
        if m:
            r, op, ty, a, b = m.groups()
            args = [a, b]
        else:
            m = ext.match(line)
            if not m:
                continue
            r, ty, op, rest = m.groups()
            args = rest.split()
        if r in kept:
            continue
        first = types.get(args[0])
        if op == "OpDot" and ty == f32 and first in vec32:
            sites[i] = (r, ty, op, args + [vec32[first]])
        elif op == "OpMatrixTimesVector" and ty in vec32 and first in matrices:
            sites[i] = (r, ty, op, args + [matrices[first]])
        elif op == "Cross" and vec32.get(ty) == 3:
            sites[i] = (r, ty, op, args)
        elif op in ("Length", "Normalize") and first in vec32:
            sites[i] = (r, ty, op, args + [vec32[first]])
        elif op == "FMix" and (ty == f32 or ty in vec32):
            sites[i] = (r, ty, op, args)
    return sites


def builtin_chain(t, glsl, result, ty, op, args, reverse=False):
    """The instructions computing the built-in `op` as a GPU that fuses may: a product rounded,
    then one fused multiply-add per further term (dot products and matrix-vector products term
    by term in order, or with `reverse` from the last term; a cross product's component as
    x·y − (z·w rounded), or with `reverse` (x·y rounded) − z·w fused; a length the square root
    of the chained dot; mix(x, y, a) as (y − x)·a + x fused). Each fused step is f64 arithmetic
    rounded once to f32, as for `Fma`. (lines, ids to mark NoContraction)."""
    steps, exact = [], []

    def emit(instruction, ident=None, f64_arithmetic=False):
        ident = ident or t.fresh()
        steps.append(f"{ident} = {instruction}")
        if f64_arithmetic:
            exact.append(ident)
        return ident

    def widen(x, ty32):
        return emit(f"OpFConvert {t.wide(ty32)} {x}")

    def chain(terms, ty32, scale_op, ident):
        """sum of products, first rounded, then fused one by one; terms: [(x, y)] in f64."""
        ty64 = t.wide(ty32)
        acc = None
        if reverse:
            terms = terms[::-1]
        for k, (x, y) in enumerate(terms):
            product = emit(f"{scale_op} {ty64} {x} {y}", f64_arithmetic=True)
            if acc is not None:
                product = emit(f"OpFAdd {ty64} {product} {widen(acc, ty32)}", f64_arithmetic=True)
            last = k == len(terms) - 1
            acc = emit(f"OpFConvert {ty32} {product}", ident if last else None, f64_arithmetic=True)
        return acc

    def dot(a, b, n, ident=None):
        terms = []
        for k in range(n):
            pair = [widen(emit(f"OpCompositeExtract {t.f32} {v} {k}"), t.f32) for v in (a, b)]
            terms.append(pair)
        return chain(terms, t.f32, "OpFMul", ident)

    if op == "OpDot":
        a, b, n = args
        dot(a, b, n, result)
    elif op == "Length":
        x, n = args
        emit(f"OpExtInst {ty} {glsl} Sqrt {dot(x, x, n)}", result)
    elif op == "Normalize":
        x, n = args
        inverse = emit(f"OpExtInst {t.f32} {glsl} InverseSqrt {dot(x, x, n)}")
        emit(f"OpVectorTimesScalar {ty} {x} {inverse}", result)
    elif op == "OpMatrixTimesVector":
        matrix, v, columns = args
        terms = []
        for k in range(columns):
            column = widen(emit(f"OpCompositeExtract {ty} {matrix} {k}"), ty)
            terms.append((column, widen(emit(f"OpCompositeExtract {t.f32} {v} {k}"), t.f32)))
        chain(terms, ty, "OpVectorTimesScalar", result)
    elif op == "Cross":
        x, y = args
        # cross(x, y) = x.yzx * y.zxy - y.yzx * x.zxy, the second product rounded alone.
        a, b, c, d = (widen(emit(f"OpVectorShuffle {ty} {v} {v} {order}"), ty)
                      for v, order in ((x, "1 2 0"), (y, "2 0 1"), (y, "1 2 0"), (x, "2 0 1")))
        ty64 = t.wide(ty)
        (a, b), (c, d) = ((c, d), (a, b)) if reverse else ((a, b), (c, d))
        rounded = widen(emit(f"OpFConvert {ty} {emit(f'OpFMul {ty64} {c} {d}', f64_arithmetic=True)}",
                             f64_arithmetic=True), ty)
        fused_product = emit(f"OpFMul {ty64} {a} {b}", f64_arithmetic=True)
        difference = emit(f"OpFSub {ty64} {rounded if reverse else fused_product} "
                          f"{fused_product if reverse else rounded}", f64_arithmetic=True)
        emit(f"OpFConvert {ty} {difference}", result)
    elif op == "FMix":
        x, y, a = args
        step = emit(f"OpFSub {ty} {y} {x}")
        exact.append(step)  # a GPU rounds y - x on its own; lavapipe must not fuse it either
        ty64 = t.wide(ty)
        product = emit(f"OpFMul {ty64} {widen(step, ty)} {widen(a, ty)}", f64_arithmetic=True)
        emit(f"OpFConvert {ty} {emit(f'OpFAdd {ty64} {product} {widen(x, ty)}', f64_arithmetic=True)}",
             result)
    return steps, exact


def target_env(text):
    version = re.search(r"^; Version: (\d+)\.(\d+)", text, re.M).groups()
    return "spv{}.{}".format(*version)


def rewrite_all(contract=False, builtins=False, reverse=False):
    sites = modules = 0
    chains = collections.Counter()
    with tempfile.TemporaryDirectory() as tmp:
        for spv in sorted(SPIRV.rglob("*.spv")):
            text = run("spirv-dis", "--raw-id", "--no-color", str(spv))
            new, (fused, chained) = rewrite(text, contract, builtins, reverse)
            if fused + sum(chained.values()) == 0:
                continue
            asm = pathlib.Path(tmp) / "m.spvasm"
            asm.write_text(new)
            env = target_env(text)
            run("spirv-as", "--preserve-numeric-ids", "--target-env", env, "-o", str(spv), str(asm))
            run("spirv-val", "--target-env", "vulkan1.2" if env <= "spv1.5" else "vulkan1.3", str(spv))
            sites += fused
            chains += chained
            modules += 1
    what = f"{sites} Fma" + (" and contractible products and sums" if contract else "")
    if builtins:
        kinds = ", ".join(f"{n} {NAMES[k]}" for k, n in chains.most_common())
        what += (f", {sum(chains.values())} dot, matrix-vector and cross products, lengths,"
                 f" normalizations and mixes as multiply-add chains ({kinds})"
                 + (" from their last term," if reverse else ","))
    print(f"fused_fma: {what} in {modules} modules now computed once rounded", flush=True)


def main():
    args = sys.argv[1:]
    contract = "--fma-only" not in args
    builtins = contract and "--no-builtins" not in args
    reverse = "--reverse" in args
    args = [a for a in args if a not in ("--fma-only", "--no-builtins", "--reverse")]
    if args == ["--rewrite-only"]:
        clean = subprocess.run(["git", "diff", "--quiet", "--", "spirv"], cwd=ROOT)
        if clean.returncode != 0:
            sys.exit("fused_fma: spirv/ has changes; commit them first (git restores it after)")
        rewrite_all(contract, builtins, reverse)
        return
    backup = tempfile.TemporaryDirectory()
    saved = pathlib.Path(backup.name) / "spirv"
    shutil.copytree(SPIRV, saved)
    try:
        rewrite_all(contract, builtins, reverse)
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
