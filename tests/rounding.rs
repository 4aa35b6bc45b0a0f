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
    common::assert_none(
        &wrong,
        format!(
            "of {} results not rounded like the CPU's (case, expected, got)",
            cases.len()
        ),
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

/// Random matrices and vectors (floats of exponents −20..20, `Rng::float`) run through
/// `glsl/checks/transform.comp`: each case's matrix, vector and twelve result words
/// (transform_point(m, v.xyz), m · v, dot(m[0], v), three unused).
fn matrix_cases(ctx: &penumbra::Context, seed: u64) -> Vec<(glam::Mat4, glam::Vec4, Vec<u32>)> {
    use glam::{Mat4, Vec4};
    let mut rng = Rng(seed);
    let cases: Vec<[[u32; 4]; 5]> = (0..4096)
        .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| rng.float().to_bits())))
        .collect();
    let got = common::run_check(ctx, "checks/transform.comp", &cases, cases.len(), 12);
    let floats = |w: [u32; 4]| Vec4::from_array(w.map(f32::from_bits));
    cases
        .iter()
        .zip(got.chunks(12))
        .map(|(c, r)| {
            let m = Mat4::from_cols(floats(c[0]), floats(c[1]), floats(c[2]), floats(c[3]));
            (m, floats(c[4]), r.to_vec())
        })
        .collect()
}

/// `transform_point` (glsl/include/transform.glsl), which the shadow-map lookups and the
/// rasterizers' vertices go through, equals its twin `cpu::transform::transform_point` to the
/// bit: its order is fixed and it is `precise`, where `m * v`'s order and fusing are the
/// device's (the next test prints what lavapipe's are). The cases tell the orders apart: the
/// twin summed from the translation instead differs from it on thousands of components.
#[test]
fn transform_point_is_its_twin_to_the_bit() {
    use penumbra::cpu::transform::transform_point;
    let ctx = common::context();
    let (mut wrong, mut telling) = (Vec::new(), 0);
    for (m, v, r) in matrix_cases(&ctx, 0x7a4e_5f0a) {
        let p = v.truncate();
        let twin = transform_point(m, p);
        if twin.to_array().map(f32::to_bits) != r[..4] {
            wrong.push((m, p, twin, r[..4].to_vec()));
        }
        let reversed = ((m.w_axis + m.z_axis * p.z) + m.y_axis * p.y) + m.x_axis * p.x;
        telling += (0..4)
            .filter(|&k| twin[k].to_bits() != reversed[k].to_bits())
            .count();
    }
    assert!(telling > 1000, "too few cases where the order tells");
    common::assert_none(&wrong, "of 4096 transforms not the twin's");
    common::assert_clean(&ctx.validation());
}

/// `m * v` and `dot` within rounding of the exact sum in whatever order the device takes,
/// fused or not: |result − Σ xⱼyⱼ| ≤ γ₄ Σ |xⱼyⱼ| (γₙ = nu / (1 − nu), u = 2⁻²⁴: the bound of
/// any order of four rounded products and three rounded sums, and of any fused chain). Which
/// order is printed, not asserted (SPIR-V leaves it to the device; tools/fused_fma.py chains
/// fused from the first term, or with `--reverse` from the last): for each of the four
/// candidates — unfused or fused, from the first term or the last — on how many of the cases
/// where they differ the device gives its bits. Code whose result must not hang on it uses
/// `transform_point` or spells its sums out under `precise`.
#[test]
fn dot_and_matrix_products_are_within_rounding_in_the_devices_order() {
    let ctx = common::context();
    let names = [
        "unfused from the first term",
        "unfused from the last",
        "fused from the first",
        "fused from the last",
    ];
    let candidates = |x: [f32; 4], y: [f32; 4]| -> [u32; 4] {
        let plain = |order: [usize; 4]| {
            let first = x[order[0]] * y[order[0]];
            order[1..].iter().fold(first, |s, &j| s + x[j] * y[j])
        };
        let fused = |order: [usize; 4]| {
            let first = x[order[0]] * y[order[0]];
            order[1..].iter().fold(first, |s, &j| x[j].mul_add(y[j], s))
        };
        let (up, down) = ([0, 1, 2, 3], [3, 2, 1, 0]);
        [plain(up), plain(down), fused(up), fused(down)].map(f32::to_bits)
    };
    let u = f64::from(f32::EPSILON) / 2.0;
    let gamma4 = 4.0 * u / (1.0 - 4.0 * u);
    let mut out_of_bound = Vec::new();
    let mut check = |found: u32, x: [f32; 4], y: [f32; 4]| {
        let terms = [0, 1, 2, 3].map(|j| f64::from(x[j]) * f64::from(y[j]));
        let exact: f64 = terms.iter().sum();
        let size: f64 = terms.iter().map(|t| t.abs()).sum();
        let got = f64::from(f32::from_bits(found));
        // Written so that a NaN result counts as out of bound.
        let within = (got - exact).abs() <= gamma4 * size;
        if !within {
            out_of_bound.push((x, y, got, exact));
        }
    };
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
    for (m, v, r) in matrix_cases(&ctx, 0x0bde_75ca) {
        let v = v.to_array();
        for k in 0..4 {
            let row = [m.x_axis[k], m.y_axis[k], m.z_axis[k], m.w_axis[k]];
            check(r[4 + k], row, v);
            tally(
                r[4 + k],
                candidates(row, v),
                &mut matrix,
                &mut matrix_telling,
            );
        }
        let column = m.x_axis.to_array();
        check(r[8], column, v);
        tally(r[8], candidates(column, v), &mut dot, &mut dot_telling);
    }
    let describe = |counts: [usize; 4], telling: usize| {
        let parts: Vec<_> = names
            .iter()
            .zip(counts)
            .map(|(name, n)| format!("{name} {n}"))
            .collect();
        format!("{} (of {telling})", parts.join(", "))
    };
    eprintln!("m * v: {}", describe(matrix, matrix_telling));
    eprintln!("dot: {}", describe(dot, dot_telling));
    assert!(
        matrix_telling > 4000 && dot_telling > 1000,
        "too few telling cases"
    );
    common::assert_none(
        &out_of_bound,
        "results past γ₄ Σ|xⱼyⱼ| of the exact sum (x, y, got, exact)",
    );
    common::assert_clean(&ctx.validation());
}
