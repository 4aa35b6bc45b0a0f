//! Procedural scenes, from specs `name[:size][@light]`.
//!
//! These exist for what files cannot do well: size sweeps (`grid:N` to 50 M triangles) and the
//! known hard cases for shadow maps (thin occluders, grazing light). Each scene picks its own
//! camera (512 × 384), light placement and technique defaults so that its shadows are clearly
//! in view; `@point` (default), `@rect` or `@directional` only changes the kind of light, which
//! is placed along the same key direction, so the three are comparable.
//!
//! Everything is deterministic (a fixed-seed LCG and a coordinate hash, no RNG crate): the same
//! spec always yields the same triangles, which the ground-truth comparisons rely on.
//! Occluders are merged into one mesh per scene so that a 100 000-object scene does not become
//! 100 000 draw calls.

use std::path::PathBuf;

use glam::{Mat4, Quat, Vec3};

use crate::scene::{shapes, transform_mesh, Camera, Light, Mesh, Scene, SceneDefaults};
use crate::{Error, Result};

/// The largest size knob any spec accepts.
pub const MAX_SIZE: u64 = 50_000_000;

/// `(name, description)` of every procedural scene, for [`Scene::list_procedural`].
pub const LIST: &[(&str, &str)] = &[
    (
        "plane-boxes",
        "ground plane with N box and sphere occluders, some floating (N = occluder count, \
         default 6, max 100000)",
    ),
    (
        "grid",
        "wavy heightfield sheet with round holes floating above a ground plane: a complex \
         shadow (N = approximate triangle count, default 100000, max 50000000)",
    ),
    (
        "thin-bars",
        "N long thin bars (width 1/200 of their length) above a plane: the hard case for \
         shadow maps (N = bar count, default 12, max 100000)",
    ),
    (
        "lattice",
        "flat lattice of N x N crossed thin bars parallel to the ground, seen from low down \
         across its shadow: a pattern finer than the pixels toward the horizon (the PVSSM \
         paper's Fig. 11 grid; N = bars per side, default 96, max 2000)",
    ),
    (
        "grazing-plane",
        "large plane lit about 85 degrees from its normal, one box occluder: the shadow-acne \
         stress case (takes no size)",
    ),
];

/// Which kind of light a spec asked for.
#[derive(Clone, Copy, Debug, PartialEq)]
enum LightKind {
    Point,
    Rect,
    Directional,
}

/// Builds the scene for `spec`. Bad specs are [`Error::Input`] with the spec as the path.
pub fn build(spec: &str) -> Result<Scene> {
    let bad = |message: String| {
        let names: Vec<&str> = LIST.iter().map(|(n, _)| *n).collect();
        Error::input(
            spec,
            None,
            format!(
                "{message}; expected name[:size][@light] with name one of {} and light one of \
                 point, rect, directional",
                names.join(", ")
            ),
        )
    };
    let (body, light) = match spec.split_once('@') {
        None => (spec, LightKind::Point),
        Some((body, "point")) => (body, LightKind::Point),
        Some((body, "rect")) => (body, LightKind::Rect),
        Some((body, "directional")) => (body, LightKind::Directional),
        Some((_, other)) => return Err(bad(format!("unknown light '{other}'"))),
    };
    let (name, size) = match body.split_once(':') {
        None => (body, None),
        Some((name, text)) => {
            let digits: String = text.chars().filter(|&c| c != '_').collect();
            let n: u64 = digits
                .parse()
                .map_err(|_| bad(format!("size '{text}' is not a whole number")))?;
            if n == 0 || n > MAX_SIZE {
                return Err(bad(format!("size {n} is out of range 1..={MAX_SIZE}")));
            }
            (name, Some(n))
        }
    };
    let sized = |default: u64, max: u64| -> Result<usize> {
        let n = size.unwrap_or(default);
        if n > max {
            return Err(bad(format!("{name} takes at most {max}, got {n}")));
        }
        Ok(n as usize)
    };
    let (canonical_size, built) = match name {
        "plane-boxes" => {
            let n = sized(6, 100_000)?;
            (Some(n), plane_boxes(n, light))
        }
        "grid" => {
            let n = sized(100_000, MAX_SIZE)?;
            (Some(n), grid(n, light))
        }
        "thin-bars" => {
            let n = sized(12, 100_000)?;
            (Some(n), thin_bars(n, light))
        }
        "lattice" => {
            let n = sized(96, 2000)?;
            (Some(n), lattice(n, light))
        }
        "grazing-plane" => {
            if size.is_some() {
                return Err(bad("grazing-plane takes no size".to_owned()));
            }
            (None, grazing_plane(light))
        }
        other => return Err(bad(format!("unknown procedural scene '{other}'"))),
    };
    let (meshes, camera, light_value, defaults) = built;
    let kind = match light {
        LightKind::Point => "point",
        LightKind::Rect => "rect",
        LightKind::Directional => "directional",
    };
    let name = match canonical_size {
        Some(n) => format!("{name}:{n}@{kind}"),
        None => format!("{name}@{kind}"),
    };
    Ok(Scene {
        name,
        source: PathBuf::from(spec),
        meshes,
        camera,
        light: light_value,
        defaults,
    })
}

type Built = (Vec<Mesh>, Camera, Light, SceneDefaults);

/// Accumulates transformed shapes into one mesh.
struct MeshBuilder {
    name: &'static str,
    positions: Vec<Vec3>,
    indices: Vec<u32>,
}

impl MeshBuilder {
    fn new(name: &'static str) -> Self {
        MeshBuilder {
            name,
            positions: Vec::new(),
            indices: Vec::new(),
        }
    }

    fn push(&mut self, (positions, indices): shapes::Geometry, transform: Mat4) {
        let mesh = transform_mesh(String::new(), positions, indices, &transform);
        // Specs cap sizes well below 2^32 vertices, so the base fits.
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&mesh.positions);
        self.indices.extend(mesh.indices.iter().map(|&i| base + i));
    }

    fn finish(self) -> Mesh {
        Mesh {
            name: self.name.to_owned(),
            positions: self.positions,
            indices: self.indices,
        }
    }
}

/// A ground plane of `size` × `size` at y = 0, split into `subdivisions`² cells.
fn ground(size: f32, subdivisions: u32) -> Mesh {
    let (positions, indices) = shapes::plane(size, size, subdivisions);
    transform_mesh("ground".to_owned(), positions, indices, &Mat4::IDENTITY)
}

/// A 512 × 384 camera with a 45° vertical field of view.
fn camera(position: Vec3, target: Vec3) -> Camera {
    Camera {
        position,
        target,
        up: Vec3::Y,
        fov_y_deg: 45.0,
        width: 512,
        height: 384,
        near: 0.1,
        far: 100.0,
    }
}

/// A light of `kind` placed `distance` from `target` along `key` (towards the light).
///
/// A rect light is a `rect_size` square facing the target (u × v points at it); a directional
/// light travels along -`key` with the sun's angular diameter (0.5°).
fn light(kind: LightKind, target: Vec3, key: Vec3, distance: f32, rect_size: f32) -> Light {
    let key = key.normalize_or(Vec3::Y);
    let position = target + key * distance;
    match kind {
        LightKind::Point => Light::Point { position },
        LightKind::Rect => {
            let facing = -key;
            let u = key.cross(Vec3::Y).try_normalize().unwrap_or(Vec3::X);
            let v = facing.cross(u);
            Light::Rect {
                position,
                u: u * rect_size,
                v: v * rect_size,
            }
        }
        LightKind::Directional => Light::Directional {
            direction: -key,
            angular_diameter_deg: 0.5,
        },
    }
}

/// A 64-bit LCG (Knuth's MMIX constants): small, deterministic, good enough for placement.
struct Lcg(u64);

impl Lcg {
    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        let unit = (self.0 >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * unit
    }
}

/// A hash of integer coordinates to [0, 1) (splitmix64 finaliser).
fn hash2(i: i64, j: i64, salt: u64) -> f32 {
    let mut x = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (j as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ salt;
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^= x >> 31;
    (x >> 40) as f32 / (1u64 << 24) as f32
}

fn plane_boxes(n: usize, kind: LightKind) -> Built {
    let per_side = (n as f64).sqrt().ceil().max(1.0) as usize;
    let cell = 14.0 / per_side as f32;
    // Keep the triangle count reasonable when there are thousands of spheres.
    let segments = match per_side {
        0..=8 => 32,
        9..=32 => 16,
        _ => 8,
    };
    let mut rng = Lcg(0x5EED_0001);
    let mut occluders = MeshBuilder::new("occluders");
    for k in 0..n {
        let (gi, gj) = ((k % per_side) as f32, (k / per_side) as f32);
        let x = -7.0 + cell * (gi + 0.5 + rng.range(-0.15, 0.15));
        let z = -7.0 + cell * (gj + 0.5 + rng.range(-0.15, 0.15));
        let s = cell * rng.range(0.35, 0.55);
        if k % 2 == 0 {
            let h = s * rng.range(0.8, 2.0);
            // Every other box floats, so shadows detach from their casters.
            let lift = if k % 4 == 2 { s * 0.6 } else { 0.0 };
            let yaw = Quat::from_rotation_y(rng.range(0.0, std::f32::consts::FRAC_PI_2));
            let t = Mat4::from_rotation_translation(yaw, Vec3::new(x, lift + h * 0.5, z));
            occluders.push(shapes::cuboid(Vec3::new(s, h, s)), t);
        } else {
            let r = s * 0.5;
            let lift = s * rng.range(0.0, 0.5);
            let t = Mat4::from_translation(Vec3::new(x, r + lift, z));
            occluders.push(shapes::sphere(r, segments), t);
        }
    }
    let target = Vec3::new(0.0, 0.0, 0.5);
    (
        vec![ground(24.0, 1), occluders.finish()],
        camera(Vec3::new(0.0, 13.0, 17.0), target),
        light(kind, Vec3::ZERO, Vec3::new(-0.6, 1.0, 0.35), 16.0, 2.0),
        SceneDefaults::default(),
    )
}

/// Height of the `grid` sheet at (x, z): two crossed waves.
fn sheet_height(x: f32, z: f32) -> f32 {
    3.0 + 0.35 * (1.1 * x + 0.3).sin() * (0.8 * z).cos() + 0.15 * (2.3 * (x + z)).sin()
}

/// Whether (x, z) lies in one of the `grid` sheet's holes: one per 1.5 × 1.5 lattice cell,
/// jittered and sized by a hash, and small enough never to leave its lattice cell.
fn in_hole(x: f32, z: f32) -> bool {
    const SPACING: f32 = 1.5;
    let (ci, cj) = ((x / SPACING).floor(), (z / SPACING).floor());
    let (i, j) = (ci as i64, cj as i64);
    let centre_x = (ci + 0.5 + 0.26 * (hash2(i, j, 1) - 0.5)) * SPACING;
    let centre_z = (cj + 0.5 + 0.26 * (hash2(i, j, 2) - 0.5)) * SPACING;
    let radius = 0.25 + 0.3 * hash2(i, j, 3);
    let (dx, dz) = (x - centre_x, z - centre_z);
    dx * dx + dz * dz < radius * radius
}

fn grid(n: usize, kind: LightKind) -> Built {
    const EXTENT: f32 = 12.0;
    let cell_centre = |i: usize, r: usize| (i as f32 + 0.5) / r as f32 * EXTENT - EXTENT * 0.5;
    let kept_cells = |r: usize| {
        (0..r * r)
            .filter(|&c| !in_hole(cell_centre(c % r, r), cell_centre(c / r, r)))
            .count()
    };
    // About 78 % of the sheet survives the holes; grow the resolution until the kept cells
    // give at least n triangles (two per cell).
    let mut r = ((n as f64 / 2.0 / 0.78).sqrt().ceil() as usize).max(1);
    let mut kept = kept_cells(r);
    while kept * 2 < n {
        r += (r / 100).max(1);
        kept = kept_cells(r);
    }
    let row = r + 1;
    let mut positions = Vec::with_capacity(row * row);
    for j in 0..row {
        let z = j as f32 / r as f32 * EXTENT - EXTENT * 0.5;
        for i in 0..row {
            let x = i as f32 / r as f32 * EXTENT - EXTENT * 0.5;
            positions.push(Vec3::new(x, sheet_height(x, z), z));
        }
    }
    let mut indices = Vec::with_capacity(kept * 6);
    let row32 = row as u32;
    for j in 0..r {
        for i in 0..r {
            if in_hole(cell_centre(i, r), cell_centre(j, r)) {
                continue;
            }
            let a = j as u32 * row32 + i as u32;
            // Same winding as `shapes::plane`: the sheet faces +Y.
            indices.extend_from_slice(&[a, a + row32, a + 1, a + 1, a + row32, a + row32 + 1]);
        }
    }
    let sheet = Mesh {
        name: "sheet".to_owned(),
        positions,
        indices,
    };
    (
        vec![ground(30.0, 1), sheet],
        camera(Vec3::new(2.0, 13.0, 19.0), Vec3::new(1.5, 0.5, 0.0)),
        light(kind, Vec3::ZERO, Vec3::new(-0.9, 1.5, 0.3), 18.0, 1.5),
        SceneDefaults {
            shadow_map_size: 2048,
            ..SceneDefaults::default()
        },
    )
}

fn thin_bars(n: usize, kind: LightKind) -> Built {
    const LENGTH: f32 = 8.0;
    const WIDTH: f32 = LENGTH / 200.0;
    let mut bars = MeshBuilder::new("bars");
    for k in 0..n {
        let t = (k as f32 + 0.5) / n as f32;
        let z = -3.5 + 7.0 * t;
        // A fan of angles and golden-ratio heights so the shadows cross at many slopes.
        let yaw = (-30.0 + 60.0 * t).to_radians();
        let y = 0.6 + 0.8 * (k as f32 * 0.618_034).fract();
        let transform =
            Mat4::from_rotation_translation(Quat::from_rotation_y(yaw), Vec3::new(0.0, y, z));
        bars.push(shapes::cuboid(Vec3::new(LENGTH, WIDTH, WIDTH)), transform);
    }
    (
        vec![ground(20.0, 1), bars.finish()],
        camera(Vec3::new(0.0, 8.0, 11.0), Vec3::new(0.0, 0.3, 0.5)),
        light(kind, Vec3::ZERO, Vec3::new(-0.35, 1.0, 0.25), 10.0, 0.5),
        SceneDefaults {
            shadow_map_size: 2048,
            ..SceneDefaults::default()
        },
    )
}

/// The PVSSM paper's Fig. 11 setting: one large grid parallel to the floor, its shadow seen
/// obliquely so that, toward the horizon, many lattice periods fall in one pixel — where the
/// paper finds its filter over the pixel's footprint as good as 32 × 32 supersampling (the
/// README's anti-aliasing section measures it). The camera looks along the lattice from below
/// its height, so the ground under it is in view (and one smooth surface, as the anti-aliasing
/// suite scores). The light is above the lattice's centre, so its shadow map's texels fall
/// evenly on the ground.
fn lattice(n: usize, kind: LightKind) -> Built {
    const EXTENT: f32 = 24.0;
    const HEIGHT: f32 = 2.0;
    let period = EXTENT / n as f32;
    let width = 0.35 * period;
    let thickness = 0.25 * width;
    let mut bars = MeshBuilder::new("lattice");
    for k in 0..n {
        let along = -0.5 * EXTENT + (k as f32 + 0.5) * period;
        // The bars along z sit one thickness lower, so the crossings do not share a plane.
        bars.push(
            shapes::cuboid(Vec3::new(EXTENT, thickness, width)),
            Mat4::from_translation(Vec3::new(0.0, HEIGHT, along - 0.5 * EXTENT + 6.0)),
        );
        bars.push(
            shapes::cuboid(Vec3::new(width, thickness, EXTENT)),
            Mat4::from_translation(Vec3::new(along, HEIGHT - thickness, 6.0 - 0.5 * EXTENT)),
        );
    }
    let centre = Vec3::new(0.0, 0.0, 6.0 - 0.5 * EXTENT);
    (
        vec![ground(2.0 * EXTENT, 1), bars.finish()],
        camera(Vec3::new(0.0, 1.2, 9.0), Vec3::new(0.0, 0.0, -8.0)),
        light(kind, centre, Vec3::new(0.15, 1.0, 0.1), 16.0, 1.0),
        SceneDefaults {
            shadow_map_size: 2048,
            ..SceneDefaults::default()
        },
    )
}

fn grazing_plane(kind: LightKind) -> Built {
    let mut occluder = MeshBuilder::new("occluder");
    occluder.push(
        shapes::cuboid(Vec3::ONE),
        Mat4::from_translation(Vec3::new(-4.0, 0.5, 0.0)),
    );
    let elevation = 85f32.to_radians();
    let key = Vec3::new(-elevation.sin(), elevation.cos(), 0.0);
    (
        // Tessellated so that interpolated depth and per-vertex attributes vary across it, as
        // they would on a real terrain.
        vec![ground(40.0, 16), occluder.finish()],
        camera(Vec3::new(0.0, 9.0, 15.0), Vec3::new(2.0, 0.0, 0.0)),
        light(kind, Vec3::ZERO, key, 30.0, 2.0),
        // The technique defaults on purpose: this scene shows how much acne they leave.
        SceneDefaults::default(),
    )
}
