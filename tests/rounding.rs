//! The rounding helpers the shadow-map code uses so that a GPU whose division is approximate
//! (Vulkan allows 2.5 ulp; NVIDIA's multiplies by an approximate reciprocal) still computes its
//! CPU twins' f32 bits: `div_rn` (glsl/include/div_rn.glsl) and `share_count`
//! (glsl/include/share.glsl), run by `glsl/checks/rounding.comp` from quotients handed to them
//! up to 3 ulp off the device's own — the error they correct — and compared bit for bit with
//! Rust's correctly rounded f32 division. On lavapipe, whose division rounds correctly, this is
//! the only way the correction runs at all; on an NVIDIA H200 their absence put a flat receiver
//! behind its own shadow-map texels and izb-soft's 12 / 24 an ulp off its twin.

mod common;

use common::Rng;

/// Runs the cases (a bits, b bits, ulps off, mode) on the GPU: each result's bits.
fn run(ctx: &penumbra::Context, cases: &[[u32; 4]]) -> Vec<u32> {
    common::run_check(ctx, "checks/rounding.comp", cases, cases.len(), 1)
}

/// Runs the cases and compares every result's bits with `expected` (the CPU's f32 arithmetic).
fn check(ctx: &penumbra::Context, cases: &[[u32; 4]], expected: impl Fn(&[u32; 4]) -> f32) {
    let got = run(ctx, cases);
    let wrong: Vec<_> = cases
        .iter()
        .zip(&got)
        .filter(|(c, &g)| g != expected(c).to_bits())
        .map(|(c, &g)| (c, expected(c), f32::from_bits(g)))
        .collect();
    assert!(
        wrong.is_empty(),
        "{} of {} results not rounded like the CPU's (case, expected, got), e.g. {:?}",
        wrong.len(),
        cases.len(),
        &wrong[..wrong.len().min(5)]
    );
    common::assert_clean(&ctx.validation());
}

impl Rng {
    /// A float of random sign, mantissa and an exponent in [-20, 20).
    fn float(&mut self) -> f32 {
        let r = self.next();
        let sign = ((r >> 63) as u32) << 31;
        let exponent = (127 - 20 + (r >> 32) % 40) as u32;
        f32::from_bits(sign | exponent << 23 | (r as u32 & 0x7F_FFFF))
    }
}

const OFFSETS: [i32; 7] = [-3, -2, -1, 0, 1, 2, 3];

#[test]
fn div_rn_rounds_like_the_cpu_from_quotients_a_few_ulps_off() {
    let ctx = common::context();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut pairs: Vec<(f32, f32)> = (0..20_000).map(|_| (rng.float(), rng.float())).collect();
    // The shadow-map code's own kind of quotient: a light-space depth z / w near 1, and the
    // linear depth near*ndc / (far*(1 - ndc) + near*ndc) of an ndc near 1.
    for i in 0..2_000 {
        let w = 3.0 + i as f32 * 1e-3;
        pairs.push((w * (1.0 - 1e-6 * i as f32), w));
        let ndc = 1.0 - (i + 1) as f32 * 6e-8;
        pairs.push((0.1 * ndc, 50.0 * (1.0 - ndc) + 0.1 * ndc));
    }
    // Exact quotients, where the correction must leave the result alone.
    pairs.extend([
        (1.0, 1.0),
        (3.0, 1.5),
        (-6.0, 2.0),
        (0.75, -0.25),
        (1.0, 3.0),
    ]);
    // div_rn from quotients up to 3 ulp off the device's (mode 0), and its last step alone from
    // quotients an ulp off the CPU's (mode 2: the step corrects one ulp, and an approximate
    // divider's own quotient may be further off; after the Newton step it rarely has anything
    // to change).
    let cases: Vec<[u32; 4]> = pairs
        .iter()
        .flat_map(|&(a, b)| {
            let whole = OFFSETS.map(|k| [a.to_bits(), b.to_bits(), k as u32, 0]);
            let q = (a / b).to_bits() as i32;
            let last = [-1i32, 0, 1].map(|k| [a.to_bits(), b.to_bits(), (q + k) as u32, 2]);
            whole.into_iter().chain(last)
        })
        .collect();
    check(&ctx, &cases, |c| {
        f32::from_bits(c[0]) / f32::from_bits(c[1])
    });
}

#[test]
fn share_count_rounds_like_the_cpu_for_every_count_up_to_1024() {
    let ctx = common::context();
    let mut cases = Vec::new();
    for whole in 1..=1024u32 {
        // Every part of the small wholes, a spread of parts for the rest (none of 0: the
        // shaders decide an empty count without dividing).
        let step = if whole <= 64 { 1 } else { 7 };
        for part in (1..=whole).step_by(step) {
            for k in OFFSETS {
                cases.push([part, whole, k as u32, 1]);
            }
        }
    }
    check(&ctx, &cases, |c| {
        if c[0] >= c[1] {
            1.0
        } else {
            c[0] as f32 / c[1] as f32
        }
    });
}

/// The specialization constant that lets `div_rn` be the plain quotient reaches the shaders as
/// the context decided it: measured on one context, forced to the correction on another.
#[test]
fn plain_division_constant_follows_the_contexts_decision() {
    use penumbra::gpu::Division;
    let measured = common::context();
    let corrected = penumbra::Context::new(&penumbra::ContextDesc {
        correctly_rounded_division: true,
        ..penumbra::ContextDesc::validated()
    })
    .expect("context");
    assert_eq!(corrected.division(), Division::CorrectlyRounded);
    assert_eq!(corrected.division_measurement(), None);
    let m = measured
        .division_measurement()
        .expect("a measured context keeps its measurement");
    assert!(m.cases > 16_000);
    assert_eq!(measured.division(), m.division());
    println!(
        "{}: {} of {} quotients off the CPU's (e.g. {:?}): {:?}",
        measured.info().name,
        m.wrong,
        m.cases,
        m.example,
        m.division()
    );
    for (ctx, plain) in [
        (&measured, measured.division() == Division::Plain),
        (&corrected, false),
    ] {
        assert_eq!(run(ctx, &[[0, 0, 0, 3]]), vec![u32::from(plain)]);
        common::assert_clean(&ctx.validation());
    }
}

/// Where the device's division measured correctly rounded, the plain quotient the shaders then
/// use gives the bits the correction gave: every technique (the ray-cast references aside, which
/// do not divide through `div_rn`) renders the same visibility on a measured and on a corrected
/// context.
#[test]
fn plain_division_renders_what_the_correction_renders() {
    use penumbra::{Engine, TechniqueDesc, TechniqueKind};
    let measured = Engine::from_context(common::context());
    if measured.context().division() != penumbra::gpu::Division::Plain {
        println!("division not measured correctly rounded here: nothing to compare");
        return;
    }
    let corrected = Engine::new(&penumbra::ContextDesc {
        correctly_rounded_division: true,
        ..penumbra::ContextDesc::validated()
    })
    .expect("engine");
    let scene = common::small("scenes/teapot-rect.toml");
    let on_measured = measured.prepare(&scene).expect("prepare");
    let on_corrected = corrected.prepare(&scene).expect("prepare");
    let visibility = |engine: &Engine, prepared: &penumbra::PreparedScene, technique: &str| {
        let desc = TechniqueDesc::new(TechniqueKind::from_name(technique).expect("kind"));
        let mut renderer = engine.renderer_for(prepared, &desc).expect("renderer");
        renderer.render().expect("frame");
        renderer.read_visibility().expect("read")
    };
    let techniques = TechniqueKind::ALL
        .iter()
        .map(|k| k.name())
        .filter(|name| !name.starts_with("reference"));
    for technique in techniques {
        let plain = visibility(&measured, &on_measured, technique);
        let exact = visibility(&corrected, &on_corrected, technique);
        common::assert_same_bits(&format!("division-{technique}"), 128, 96, &exact, &plain);
    }
    drop((on_measured, on_corrected));
    common::assert_clean(&measured.context().validation());
    common::assert_clean(&corrected.context().validation());
}

/// `precise` keeps a product and a sum apart (SPIR-V's NoContraction): `div_rn`'s exact
/// residual (Dekker's product, glsl/include/div_rn.glsl) is only exact if it does. Cases where
/// fusing changes the result — c = −(a·b rounded), so the unfused sum is 0 and the fused one
/// a·b's rounding error — and random ones. Whether the device fuses an unmarked a·b + c or
/// `fma()` is printed, not asserted: Vulkan allows either (lavapipe fuses neither; an H200 may
/// fuse both), and code that must not be fused has to say `precise`, as `essm`'s box mean once
/// did not (glsl/essm/lookup.comp).
#[test]
fn precise_products_and_sums_are_not_fused() {
    let ctx = common::context();
    let mut rng = Rng(0x5eed_c0de);
    let cases: Vec<[u32; 4]> = (0..4096)
        .map(|k| {
            let a = 1.0 + (rng.next() % (1 << 23)) as f32 / (1 << 23) as f32;
            let b = 1.0 + (rng.next() % (1 << 23)) as f32 / (1 << 23) as f32;
            let c = if k % 2 == 0 {
                -(a * b)
            } else {
                (rng.next() % (1 << 20)) as f32 / (1 << 10) as f32 - 512.0
            };
            [a.to_bits(), b.to_bits(), c.to_bits(), 0]
        })
        .collect();
    let got = common::run_check(&ctx, "checks/contraction.comp", &cases, cases.len(), 3);
    let (mut telling, mut kept_wrong, mut loose_fused, mut fma_fused) = (0, 0, 0, 0);
    for (case, r) in cases.iter().zip(got.chunks(3)) {
        let [a, b, c] = [case[0], case[1], case[2]].map(f32::from_bits);
        let unfused = a * b + c;
        let fused = a.mul_add(b, c);
        if unfused.to_bits() == fused.to_bits() {
            continue;
        }
        telling += 1;
        kept_wrong += usize::from(r[0] != unfused.to_bits());
        loose_fused += usize::from(r[1] == fused.to_bits());
        fma_fused += usize::from(r[2] == fused.to_bits());
    }
    eprintln!(
        "{telling} cases where fusing tells: unmarked a*b + c fused in {loose_fused}, fma() in \
         {fma_fused}; precise a*b + c wrong in {kept_wrong}"
    );
    assert!(
        telling > 2000,
        "too few cases where fusing changes the result"
    );
    assert_eq!(
        kept_wrong, 0,
        "the device fused `precise` arithmetic: div_rn's residual is not exact here"
    );
    common::assert_clean(&ctx.validation());
}

/// `transform_point` (glsl/include/transform.glsl), which the shadow-map lookups and the
/// rasterizers' vertices go through, equals its twin `cpu::transform::transform_point` to the
/// bit: its order is fixed and it is `precise`, where `m * v`'s order and fusing are the
/// device's (printed: lavapipe sums the columns last to first, so never as the twin where the
/// order tells).
#[test]
fn transform_point_is_its_twin_to_the_bit() {
    use glam::{Mat4, Vec4};
    use penumbra::cpu::transform::transform_point;
    let ctx = common::context();
    let mut rng = Rng(0x7a4e_5f0a);
    let cases: Vec<[[u32; 4]; 5]> = (0..4096)
        .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| rng.float().to_bits())))
        .collect();
    let got = common::run_check(&ctx, "checks/transform.comp", &cases, cases.len(), 8);
    let floats = |w: &[u32]| Vec4::from_array(std::array::from_fn(|k| f32::from_bits(w[k])));
    let (mut wrong, mut as_twin, mut as_reversed, mut telling) = (Vec::new(), 0, 0, 0);
    for (case, r) in cases.iter().zip(got.chunks(8)) {
        let m = Mat4::from_cols(
            floats(&case[0]),
            floats(&case[1]),
            floats(&case[2]),
            floats(&case[3]),
        );
        let p = floats(&case[4]).truncate();
        let twin = transform_point(m, p);
        let reversed = ((m.w_axis + m.z_axis * p.z) + m.y_axis * p.y) + m.x_axis * p.x;
        if twin.to_array().map(f32::to_bits) != r[..4] {
            wrong.push((m, p, twin, floats(&r[..4])));
        }
        for k in 0..4 {
            if twin[k].to_bits() != reversed[k].to_bits() {
                telling += 1;
                as_twin += usize::from(r[4 + k] == twin[k].to_bits());
                as_reversed += usize::from(r[4 + k] == reversed[k].to_bits());
            }
        }
    }
    eprintln!(
        "{telling} components where the order tells: m * v as transform_point's in {as_twin}, \
         summed from the translation in {as_reversed}"
    );
    assert!(telling > 1000, "too few cases where the order tells");
    assert!(
        wrong.is_empty(),
        "{} of {} transforms not the twin's, e.g. {:?}",
        wrong.len(),
        cases.len(),
        &wrong[..wrong.len().min(3)]
    );
    common::assert_clean(&ctx.validation());
}

/// Which order the device sums `m * v` and `dot` in, and whether it fuses their products:
/// printed, not asserted (SPIR-V leaves both to the device; tools/fused_fma.py simulates the
/// chains fused from the first term, or with `--reverse` from the last, and lavapipe sums
/// `m * v` from its last column unfused). Code whose result must not hang on it uses
/// `transform_point` or spells its sums out under `precise`. Asserted: that the four orders
/// tell apart on enough cases for the counts to mean something.
#[test]
fn the_devices_dot_and_matrix_orders_are_printed() {
    let ctx = common::context();
    let mut rng = Rng(0x0bde_75ca);
    let cases: Vec<[[u32; 4]; 5]> = (0..4096)
        .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| rng.float().to_bits())))
        .collect();
    let got = common::run_check(&ctx, "checks/builtin_orders.comp", &cases, cases.len(), 8);
    // The four candidates for the sum of x[j]·y[j]: unfused from the first term or the last,
    // and chained fused multiply-adds from the first term or the last.
    let candidates = |x: [f32; 4], y: [f32; 4]| -> [u32; 4] {
        let plain = |order: [usize; 4]| {
            order
                .iter()
                .skip(1)
                .fold(x[order[0]] * y[order[0]], |s, &j| s + x[j] * y[j])
        };
        let fused = |order: [usize; 4]| {
            order
                .iter()
                .skip(1)
                .fold(x[order[0]] * y[order[0]], |s, &j| x[j].mul_add(y[j], s))
        };
        let (up, down) = ([0, 1, 2, 3], [3, 2, 1, 0]);
        [plain(up), plain(down), fused(up), fused(down)].map(f32::to_bits)
    };
    let names = [
        "unfused from the first term",
        "unfused from the last",
        "fused from the first",
        "fused from the last",
    ];
    let (mut matrix, mut dot) = ([0usize; 4], [0usize; 4]);
    let (mut matrix_telling, mut dot_telling) = (0, 0);
    let tally = |found: u32, c: [u32; 4], counts: &mut [usize; 4], telling: &mut usize| {
        if c.iter().all(|&b| b == c[0]) {
            return;
        }
        *telling += 1;
        for (n, &b) in counts.iter_mut().zip(&c) {
            *n += usize::from(found == b);
        }
    };
    for (case, r) in cases.iter().zip(got.chunks(8)) {
        let f = |w: [u32; 4]| w.map(f32::from_bits);
        let v = f(case[4]);
        for k in 0..4 {
            let row = [0, 1, 2, 3].map(|j| f32::from_bits(case[j][k]));
            tally(r[k], candidates(row, v), &mut matrix, &mut matrix_telling);
        }
        tally(r[4], candidates(f(case[0]), v), &mut dot, &mut dot_telling);
    }
    let describe = |counts: [usize; 4], telling: usize| {
        names
            .iter()
            .zip(counts)
            .map(|(name, n)| format!("{name} {n}"))
            .collect::<Vec<_>>()
            .join(", ")
            + &format!(" (of {telling})")
    };
    eprintln!("m * v: {}", describe(matrix, matrix_telling));
    eprintln!("dot: {}", describe(dot, dot_telling));
    assert!(
        matrix_telling > 4000 && dot_telling > 1000,
        "too few telling cases"
    );
    common::assert_clean(&ctx.validation());
}
