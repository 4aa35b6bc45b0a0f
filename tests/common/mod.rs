//! Test harness: a validated context, the validation oracle, and diff images on failure.
#![allow(dead_code, reason = "each test binary uses a different subset")]

pub mod bitmask;
pub mod cli;
pub mod kernels_raster;
pub mod kernels_sat;
pub mod library_api;
pub mod pcf_family;
pub mod push_twins;
pub mod pvssm;
pub mod reference;
pub mod rmsm;

use std::path::PathBuf;

use penumbra::gpu::ValidationLog;
use penumbra::{Context, ContextDesc, Engine};

/// A context with validation and synchronization validation on. Fails (never skips) when no
/// Vulkan device is present: CI has lavapipe, so a missing device is a broken setup.
pub fn context() -> Context {
    Context::new(&ContextDesc::validated()).unwrap_or_else(|e| {
        panic!("cannot create a validated Vulkan context ({e}); install the packages in tools/setup.sh")
    })
}

/// Runs `shader`, a `glsl/checks/` kernel (binding 0: the cases, binding 1: the results, one
/// invocation a case), over `cases` on `ctx`: the results buffer's words, `words_per_case` a
/// case.
pub fn run_check<T: bytemuck::Pod>(
    ctx: &Context,
    shader: &str,
    cases: &[T],
    invocations: usize,
    words_per_case: usize,
) -> Vec<u32> {
    use ash::vk;
    use penumbra::gpu::{u32s, Binding, Buffer, DescriptorSet, Pipeline};
    let pipeline = Pipeline::compute(ctx, shader).expect("pipeline");
    let input = ctx
        .buffer_with("check cases", vk::BufferUsageFlags::STORAGE_BUFFER, cases)
        .expect("cases");
    let bytes = 4 * (words_per_case * invocations) as u64;
    let output = Buffer::storage(ctx, "check results", bytes).expect("results");
    let set = DescriptorSet::new(
        ctx,
        &pipeline,
        &[Binding::Buffer(&input), Binding::Buffer(&output)],
    )
    .expect("set");
    ctx.submit(None, |rec| {
        rec.dispatch(&pipeline, &set, &(), [invocations as u32, 1, 1])
    })
    .expect("dispatch");
    u32s(&ctx.read_buffer(&output).expect("read"))
}

/// xorshift64*: the same cases every run, without an RNG crate (a test adds what it draws with
/// an `impl common::Rng` of its own).
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// An engine on a validated context.
pub fn engine() -> Engine {
    Engine::from_context(context())
}

/// Asserts that validation ran on the log's context and reported no error and no warning,
/// printing what it holds. A log whose context ran without the layers fails: its zero counts
/// would claim a check that never happened.
pub fn assert_clean(log: &ValidationLog) {
    let counts = log.counts();
    assert!(
        counts.ran,
        "validation did not run on this context (no layer or no messenger): \
         its 0 errors and 0 warnings mean nothing"
    );
    if counts.errors > 0 || counts.warnings > 0 {
        for m in log.messages() {
            eprintln!("{m}");
        }
        panic!(
            "validation reported {} errors and {} warnings",
            counts.errors, counts.warnings
        );
    }
}

/// Asserts that a check found nothing: otherwise panics with how many it found, `what` they are,
/// and the first few.
pub fn assert_none<T: std::fmt::Debug>(found: &[T], what: impl std::fmt::Display) {
    assert!(
        found.is_empty(),
        "{} {what}, e.g. {:?}",
        found.len(),
        &found[..found.len().min(4)]
    );
}

/// Where failing tests write their images.
pub fn diff_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("diffs");
    let _ = std::fs::create_dir_all(&dir);
    dir
}

/// Asserts that two `width` × `height` visibility images are the same bit for bit; where they
/// are not, writes their diff (`write_diff`) under `name` before failing with the count.
pub fn assert_same_bits(name: &str, width: u32, height: u32, expected: &[f32], actual: &[f32]) {
    assert_eq!(expected.len(), actual.len(), "{name}: image sizes differ");
    let differing = expected
        .iter()
        .zip(actual)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    if differing > 0 {
        let dir = write_diff(name, width, height, expected, actual);
        panic!(
            "{name}: {differing} samples differ; images in {}",
            dir.display()
        );
    }
}

/// Writes `expected`, `actual` and a red/green diff of two grey images as PNGs; returns the dir.
pub fn write_diff(
    name: &str,
    width: u32,
    height: u32,
    expected: &[f32],
    actual: &[f32],
) -> PathBuf {
    let dir = diff_dir();
    let grey = |v: &[f32]| -> Vec<u8> {
        v.iter()
            .map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect()
    };
    let save = |suffix: &str, data: Vec<u8>, channels: u32| {
        let path = dir.join(format!("{name}-{suffix}.png"));
        let result = if channels == 1 {
            image::GrayImage::from_raw(width, height, data).map(|i| i.save(&path))
        } else {
            image::RgbImage::from_raw(width, height, data).map(|i| i.save(&path))
        };
        if let Some(Err(e)) = result {
            eprintln!("cannot write {}: {e}", path.display());
        }
    };
    save("expected", grey(expected), 1);
    save("actual", grey(actual), 1);
    let diff: Vec<u8> = expected
        .iter()
        .zip(actual)
        .flat_map(|(e, a)| {
            let d = ((a - e) * 4.0).clamp(-1.0, 1.0);
            let m = (d.abs() * 255.0) as u8;
            if d > 0.0 {
                [0, m, 0]
            } else {
                [m, 0, 0]
            }
        })
        .collect();
    save("diff", diff, 3);
    dir
}

/// The knobs that leave a shadow-map technique's kernel alone, for comparisons with its CPU
/// twin: no light clipping (the receivers pass has its own twin, `tests/receivers.rs`) and the
/// light view fitted to the scene (what `prepared.light_view` holds).
pub const KERNEL_ONLY: [(&str, &str); 2] = [("light_clip", "0"), ("fit", "scene")];

/// A counter of `frame`; panics when the technique has none of that name.
pub fn counter(frame: &penumbra::Frame, name: &str) -> u64 {
    *frame
        .stats
        .counters
        .get(name)
        .unwrap_or_else(|| panic!("no counter {name}"))
}

/// Knob overrides from `(key, value)` pairs.
pub fn knobs(pairs: &[(&str, &str)]) -> std::collections::BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// A scene (file or procedural spec) with its camera shrunk to 128×96 for fast tests.
pub fn small(spec: &str) -> penumbra::scene::Scene {
    let mut scene = penumbra::scene::Scene::open(spec).expect("scene");
    scene.camera.width = 128;
    scene.camera.height = 96;
    scene
}

/// A small scene (see [`small`]) prepared, with its ray-cast reference (the default samples) and
/// its view samples' positions: what property tests against the reference start from.
pub fn with_reference(
    engine: &Engine,
    spec: &str,
) -> (penumbra::PreparedScene, penumbra::Frame, Vec<glam::Vec4>) {
    let prepared = engine.prepare(&small(spec)).expect("prepare");
    let reference = engine
        .render(&prepared, "reference", &knobs(&[]), 1)
        .expect("reference");
    let positions = prepared
        .view
        .read_positions(engine.context())
        .expect("positions");
    (prepared, reference, positions)
}

/// Of the view samples the reference shows fully lit, the fraction `visibility` reads below 0.9
/// (a dark halo where there is no shadow).
pub fn darkened_where_lit(positions: &[glam::Vec4], reference: &[f32], visibility: &[f32]) -> f64 {
    let (mut lit, mut dark) = (0u64, 0u64);
    for ((p, r), v) in positions.iter().zip(reference).zip(visibility) {
        if p.w > 0.0 && *r >= 1.0 {
            lit += 1;
            dark += (*v < 0.9) as u64;
        }
    }
    dark as f64 / lit.max(1) as f64
}

/// Lit, umbra and penumbra counts of `visibility` over the view samples (`w > 0` in
/// `positions`): the shaders' classes (v ≥ 1, v ≤ 0, else).
pub fn class_counts(visibility: &[f32], positions: &[glam::Vec4]) -> [u64; 3] {
    let mut counts = [0u64; 3];
    for (v, p) in visibility.iter().zip(positions) {
        if p.w > 0.0 {
            counts[if *v >= 1.0 {
                0
            } else if *v <= 0.0 {
                1
            } else {
                2
            }] += 1;
        }
    }
    counts
}

/// Asserts a frame's `lit`/`umbra`/`penumbra` counters equal the classes of its own visibility
/// image over the view samples (the shader counts what it writes); returns those classes.
pub fn assert_counters_describe_image(
    what: &str,
    counters: &std::collections::BTreeMap<String, u64>,
    visibility: &[f32],
    positions: &[glam::Vec4],
) -> [u64; 3] {
    let own = class_counts(visibility, positions);
    for (k, name) in ["lit", "umbra", "penumbra"].iter().enumerate() {
        assert_eq!(
            counters[*name], own[k],
            "{what}: counter {name} disagrees with the GPU's own image"
        );
    }
    own
}

/// Checks a GPU frame's `lit`/`umbra`/`penumbra` counters two ways that can each fail: exactly
/// against the classes of the GPU's own visibility image (the counters describe that image), and
/// against the CPU twin's counters `cpu` within `max_flip_fraction` of the view samples — a
/// declared cap on how many samples may change class by rounding, not a bound taken from the
/// images being checked. Panics naming `what`.
pub fn check_class_counters(
    what: &str,
    counters: &std::collections::BTreeMap<String, u64>,
    gpu_visibility: &[f32],
    positions: &[glam::Vec4],
    cpu: [u64; 3],
    max_flip_fraction: f64,
) {
    let own = assert_counters_describe_image(what, counters, gpu_visibility, positions);
    let samples: u64 = own.iter().sum();
    let cap = (max_flip_fraction * samples as f64).ceil() as u64;
    for (k, name) in ["lit", "umbra", "penumbra"].iter().enumerate() {
        assert!(
            counters[*name].abs_diff(cpu[k]) <= cap,
            "{what}: {name} GPU {} vs CPU {} (at most {cap} samples may change class)",
            counters[*name],
            cpu[k]
        );
    }
}

/// A bare 10 × 10 plane at y = 0 under `light`, seen from above at 128×96: every receiver is its
/// own occluder.
pub fn bare_plane(light: penumbra::scene::Light) -> penumbra::scene::Scene {
    let (positions, indices) = penumbra::scene::shapes::plane(10.0, 10.0, 1);
    penumbra::scene::Scene {
        name: "bare-plane".into(),
        source: "bare-plane".into(),
        meshes: vec![penumbra::scene::Mesh {
            name: "plane".into(),
            positions,
            indices,
        }],
        camera: penumbra::scene::Camera {
            position: glam::Vec3::new(0.0, 6.0, 2.0),
            target: glam::Vec3::ZERO,
            up: glam::Vec3::Y,
            fov_y_deg: 45.0,
            width: 128,
            height: 96,
            near: 0.1,
            far: 100.0,
        },
        light,
        defaults: penumbra::scene::SceneDefaults {
            shadow_map_size: 256,
            ..penumbra::scene::SceneDefaults::default()
        },
    }
}

/// The parallel-plane case of the soft filtered family (book §6.2.1; PCSS's own assumptions): a
/// square light of side `light_width` at height `light_height`, facing down, over an 8 × 8
/// ground plane at y = 0, and an occluder plane at height `occluder_height` covering
/// x ∈ [−4, 0], z ∈ [−3, 3] — a straight edge along z through the origin. Seen at 128×96 from
/// the +x side, low enough to see the ground under the edge. On the ground near the edge (|z| <
/// 2) the exact visibility is [`parallel_planes_visibility`].
pub fn parallel_planes(
    light_width: f32,
    occluder_height: f32,
    light_height: f32,
) -> penumbra::scene::Scene {
    use glam::Vec3;
    let (ground, ground_indices) = penumbra::scene::shapes::plane(8.0, 8.0, 1);
    let (mut occluder, occluder_indices) = penumbra::scene::shapes::plane(4.0, 6.0, 1);
    for p in &mut occluder {
        *p += Vec3::new(-2.0, occluder_height, 0.0);
    }
    penumbra::scene::Scene {
        name: "parallel-planes".into(),
        source: "parallel-planes".into(),
        meshes: vec![
            penumbra::scene::Mesh {
                name: "ground".into(),
                positions: ground,
                indices: ground_indices,
            },
            penumbra::scene::Mesh {
                name: "occluder".into(),
                positions: occluder,
                indices: occluder_indices,
            },
        ],
        camera: penumbra::scene::Camera {
            position: Vec3::new(4.0, 4.0, 0.0),
            target: Vec3::new(0.0, 0.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 128,
            height: 96,
            near: 0.1,
            far: 100.0,
        },
        light: penumbra::scene::Light::Rect {
            position: Vec3::new(0.0, light_height, 0.0),
            u: Vec3::X * light_width,
            v: Vec3::Z * light_width,
        },
        defaults: penumbra::scene::SceneDefaults {
            shadow_map_size: 512,
            ..penumbra::scene::SceneDefaults::default()
        },
    }
}

/// The exact visibility of the ground point at `x` in [`parallel_planes`]: a linear ramp of
/// width w·h/(H − h) centred on the edge (intercept theorem), V = clamp(½ + x(H − h)/(h·w)).
/// A light point at l_x sees (x, 0) past the edge when x + (l_x − x)·h/H ≥ 0.
pub fn parallel_planes_visibility(
    x: f32,
    light_width: f32,
    occluder_height: f32,
    light_height: f32,
) -> f32 {
    let (w, h, big_h) = (light_width, occluder_height, light_height);
    if w <= 0.0 {
        return if x >= 0.0 { 1.0 } else { 0.0 };
    }
    (0.5 + x * (big_h - h) / (h * w)).clamp(0.0, 1.0)
}

/// The ground samples of [`parallel_planes`] near its edge — on the ground (y ≈ 0), |z| < 2 and
/// |x| < `reach` — as (x, V).
pub fn parallel_planes_ground(
    visibility: &[f32],
    positions: &[glam::Vec4],
    reach: f32,
) -> Vec<(f32, f32)> {
    positions
        .iter()
        .zip(visibility)
        .filter(|(p, _)| p.w > 0.0 && p.y.abs() < 1e-3 && p.z.abs() < 2.0 && p.x.abs() < reach)
        .map(|(p, v)| (p.x, *v))
        .collect()
}

/// A ramp's width: the inverse slope of the least-squares line of V against x through the
/// samples strictly inside it, `band` < V < 1 − `band` (the corners, where a filter rounds the
/// ramp off, left out). Panics with fewer than 5 such samples.
pub fn ramp_width(samples: &[(f32, f32)], band: f32) -> f32 {
    let inside: Vec<(f64, f64)> = samples
        .iter()
        .filter(|(_, v)| *v > band && *v < 1.0 - band)
        .map(|&(x, v)| (x as f64, v as f64))
        .collect();
    assert!(
        inside.len() >= 5,
        "only {} samples inside the ramp",
        inside.len()
    );
    let n = inside.len() as f64;
    let (mx, mv) = inside
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, v)| (a + x / n, b + v / n));
    let (sxv, sxx) = inside.iter().fold((0.0, 0.0), |(a, b), (x, v)| {
        (a + (x - mx) * (v - mv), b + (x - mx) * (x - mx))
    });
    (sxx / sxv) as f32
}

/// Renders `technique` with `knobs` on [`parallel_planes`]`(w, h, big_h)`, asserting clean
/// validation, no NaN and no V outside [0, 1]; returns the frame and the view samples' positions.
pub fn render_parallel_planes(
    engine: &Engine,
    technique: &str,
    (w, h, big_h): (f32, f32, f32),
    knobs: &std::collections::BTreeMap<String, String>,
) -> (penumbra::engine::Frame, Vec<glam::Vec4>) {
    let prepared = engine
        .prepare(&parallel_planes(w, h, big_h))
        .expect("prepare");
    let frame = engine
        .render(&prepared, technique, knobs, 1)
        .expect("render");
    let positions = prepared
        .view
        .read_positions(engine.context())
        .expect("positions");
    assert_clean(&engine.context().validation());
    assert_eq!(frame.stats.nan_count, 0, "{technique}: NaN");
    assert_eq!(
        frame.stats.out_of_range_count, 0,
        "{technique}: V outside [0, 1]"
    );
    (frame, positions)
}

/// The item called `name` of a technique's named list (`kind` for the message).
fn named<T>(items: Vec<(&'static str, T)>, kind: &str, name: &str) -> T {
    items
        .into_iter()
        .find(|(n, _)| *n == name)
        .map(|(_, item)| item)
        .unwrap_or_else(|| panic!("no {kind} {name}"))
}

/// A technique's intermediate image (`Technique::images`) read back by name as floats.
pub fn read_named_image(
    ctx: &Context,
    technique: &dyn penumbra::techniques::Technique,
    name: &str,
) -> penumbra::Result<Vec<f32>> {
    let image = named(technique.images(), "image", name);
    Ok(penumbra::gpu::f32s(&ctx.read_image(image)?))
}

/// A technique's intermediate buffer (`Technique::buffers`) read back by name as floats.
pub fn read_named_buffer(
    ctx: &Context,
    technique: &dyn penumbra::techniques::Technique,
    name: &str,
) -> penumbra::Result<Vec<f32>> {
    let buffer = named(technique.buffers(), "buffer", name);
    Ok(penumbra::gpu::f32s(&ctx.read_buffer(buffer)?))
}

/// A technique's intermediate buffer (`Technique::buffers`) read back by name as 32-bit words.
pub fn read_named_words(
    ctx: &Context,
    technique: &dyn penumbra::techniques::Technique,
    name: &str,
) -> penumbra::Result<Vec<u32>> {
    let buffer = named(technique.buffers(), "buffer", name);
    Ok(penumbra::gpu::u32s(&ctx.read_buffer(buffer)?))
}

/// The caster test (`glsl/caster_cull/`) bound to `prepared`'s view samples and triangles at the
/// reference's tolerance, with that tolerance and the CPU twin's tile bounds of the same samples
/// (read back): what the caster tests compare.
pub fn caster_pass(
    prepared: &penumbra::engine::PreparedScene,
    ctx: &Context,
) -> (
    penumbra::passes::caster_cull::CasterCull,
    f32,
    Vec<penumbra::cpu::caster_cull::TileBounds>,
) {
    let eps = penumbra::passes::caster_cull::tolerance(&prepared.positions);
    let pass = penumbra::passes::caster_cull::CasterCull::new(
        ctx,
        &prepared.view,
        &prepared.geometry,
        &prepared.light,
        eps,
    )
    .expect("caster pass");
    let positions = prepared.view.read_positions(ctx).expect("positions");
    let normals = prepared.view.read_normals(ctx).expect("normals");
    assert_clean(&ctx.validation());
    let (w, h) = (prepared.view.width as usize, prepared.view.height as usize);
    let tiles = penumbra::cpu::caster_cull::tile_bounds(&positions, &normals, w, h);
    (pass, eps, tiles)
}
