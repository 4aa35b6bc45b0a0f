//! `cssm`: convolution soft shadow maps (Annen et al. 2008; book §6.5.5; notes
//! `book-soft-shadows.md` §7 and `seed-papers.md` part B).
//!
//! PCSS (blocker search, width from the parallel-plane model, filter) with both averages taken
//! from prefiltered images of `csm`'s Fourier basis, so each costs a constant number of table
//! reads whatever the box width. With `csm`'s series
//! f̂(z, d) = ½ + Σ_k w_k [cos(c_k d̃) sin(c_k r z) − sin(c_k d̃) cos(c_k r z)],
//! w_k = σ_k·2/c_k, c_k = π(2k − 1), r = `depth_range`, d̃ = r·d − t₀ (its offset), and its remap
//! s = (f̂ − ε)/(1 − 2ε) (affine: linear in the bases; only the final clamp is not):
//!
//! - blocker fraction over the search box R_s: mean(1 − s) ∝ (½ − ε) − Σ_k w_k [cos·S̄_k −
//!   sin·C̄_k], with S̄_k, C̄_k the box means of sin(c_k r z), cos(c_k r z);
//! - blocker depth sum: mean(z(1 − s)) ∝ (½ − ε) Z̄ − Σ_k w_k [cos·ZS̄_k − sin·ZC̄_k], the
//!   means of z, z sin(c_k r z), z cos(c_k r z) (the book's extra numerator bases);
//! - z_avg = their ratio (the common factor 1/(1 − 2ε) cancels), clamped to [0, d]. A blocker
//!   fraction below 1e-3 (`MIN_BLOCKER_FRACTION` in `lookup.comp`) is treated as lit: the
//!   ratio of two near-zero series sums is noise (counter `no_blockers`);
//! - V = clamp(½ + Σ_k w_k [cos·S̄_k − sin·C̄_k] − ε, over the filter box)/(1 − 2ε) — `csm`'s
//!   reconstruction, with its damping σ_k, offset t₀ (against self-shadowing: t₀ makes z ≈ d
//!   read lit) and remap ε (lit plateaus read exactly 1, umbrae 0): see
//!   [`super::filtered::csm`].
//!
//! Boxes follow the family's convention ([`super::soft_light`]): the search box is the light's
//! footprint at the near plane, the filter box its footprint at z_avg, both clamped between
//! [`MIN_KERNEL`] and [`MAX_WIDTH`] texels and centred at the receiver. Texels outside the map
//! are the far plane (z = 1).
//!
//! **Prefiltering: summed-area tables in u32 fixed point.** A box mean of any fractional width
//! is 16 reads per table (`sat_box_sum`), so the cost per pixel is constant in the penumbra
//! width; a mip chain would be cheaper to build but only approximates widths between levels. The
//! basis values lie in [−1, 1]: stored as (b + 1)/2 ∈ [0, 1] (affine, undone on the means),
//! each window sum is exact in wrap-around u32 ([`crate::kernels::sat`]) and the only error is
//! each texel's rounding to 2^-bits, i.e. ≤ 2^-bits on a basis mean; fp32 tables lose 5e-3 at
//! 1024² (that module's table), which the M terms would add up. `bits` is 16, fewer when
//! `max_width` allows windows of more than 2^16 texels: (⌈max_width⌉ + 2)² · 2^bits < 2^32
//! ([`fixed_bits`]; 11 at `max_width` 1024).
//!
//! **Passes.** Per frame: the D32 map; `prepare.comp` (each view sample's map position and
//! depth, once); then the *search loop*, per term k = 1..M: `encode.comp` (the five images of
//! term k), the tables (z only at k = 1), `lookup.comp` accumulating the two search sums; then
//! the *filter loop*, per term: `encode.comp`, the sin and cos tables only, `lookup.comp`
//! (resolving z_avg and the width at k = 1, accumulating, and at k = M writing V). Only the M
//! terms asked for are computed, one at a time, so memory does not grow with M; the price is the
//! sin/cos tables built twice: 6M + 1 table builds (about half the frame at M = 16 and 1024² on
//! lavapipe, ~33 ms each in a loaded run; the lookups' 16 reads per table and box are the rest).
//! `resident = 1`
//! trades memory for that time: each term's sin/cos tables are built once, in the search loop,
//! and kept, so the filter loop only reads (4M + 1 builds). Both give identical results (same
//! tables, same order of operations; `tests/cssm.rs` checks it bit for bit). Timed passes:
//! `cssm-search`, `cssm-filter`.
//!
//! **Memory per shadow-map texel** while running: 4 B (D32) + 5 × 4 B (R32F basis images) +
//! 5 × 4 B (u32 tables) = 44 B whatever M, plus a carry row per table and 2 × 16 B per view
//! sample (positions in the map, state); with `resident`, (3 + 2M) tables: 36 + 8M B (68 B at
//! M = 4, 164 B at M = 16). Each table is one storage-buffer binding, so the map is limited to
//! 4 · size² ≤ `maxStorageBufferRange` (5792² on lavapipe).
//!
//! Counters: `view_samples`, `outside_light`, `lit`, `umbra`, `penumbra`, `no_blockers`,
//! `terms`. CPU twin: [`crate::cpu::cssm`].

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Mat4, Vec2};

use super::filtered::csm::{self, DAMPING, DEPTH_RANGE, OFFSET, REMAP_MARGIN, TERMS};
use super::pcf::shadow_map_desc;
use super::soft_light::{soft_light, MAX_WIDTH, MIN_KERNEL};
use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS,
};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline, Recorder};
use crate::kernels::sat::{Sat, SatPrecision};
use crate::passes::{LightProjection, LightView, SceneGeometry, ShadowMap};

/// Counters in the shader's order, then `terms` (added by the host).
pub const COUNTER_NAMES: [&str; 6] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "no_blockers",
];

/// `FLAG_FILTER`, `FLAG_FIRST`, `FLAG_LAST` of `cssm.glsl`.
pub const FLAG_FILTER: i32 = 1;
/// First dispatch of a loop.
pub const FLAG_FIRST: i32 = 2;
/// Last dispatch of a loop.
pub const FLAG_LAST: i32 = 4;

/// `resident`: keep every term's sin/cos tables for the filter loop instead of rebuilding them.
pub const RESIDENT: Knob = Knob {
    name: "resident",
    summary: "1: keep each term's sin/cos tables from the search for the filter (2M more tables, \
              8M B/texel; the filter loop then builds nothing); 0: rebuild them",
    default: KnobDefault::Value(0.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &[],
};

const KNOBS: [Knob; 11] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    TERMS,
    DAMPING,
    OFFSET,
    DEPTH_RANGE,
    MIN_KERNEL,
    MAX_WIDTH,
    RESIDENT,
];

/// `cssm`: convolution soft shadow maps.
pub const CSSM: TechniqueInfo = TechniqueInfo {
    name: "cssm",
    summary: "convolution soft shadows: PCSS with blocker average and filter from csm's Fourier \
              basis in u32 summed-area tables",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Cssm::new(setup, params)?)),
};

/// The push-constant block of `glsl/cssm/cssm.glsl` (`encode.comp`, `lookup.comp`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CssmPush {
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map width and height.
    pub map_size: i32,
    /// Padding (keeps `near` where the shaders expect it).
    pub pad: i32,
    /// Light view near plane.
    pub near: f32,
    /// Light view far plane.
    pub far: f32,
    /// 1 for a perspective light view, 0 for orthographic.
    pub perspective: i32,
    /// k (1-based) of this dispatch's term.
    pub term: i32,
    /// `FLAG_FILTER | FLAG_FIRST | FLAG_LAST`.
    pub flags: i32,
    /// Linear depth is scaled by this before the series.
    pub depth_range: f32,
    /// The step's shift t₀ towards the light (scaled depth).
    pub offset: f32,
    /// The remap ε'.
    pub remap: f32,
    /// σ_k · 2/c_k of this dispatch's term.
    pub weight: f32,
    /// 2^bits of the fixed-point tables.
    pub scale: f32,
    /// The light's footprint factor ([`super::soft_light::SoftLight::size`]).
    pub light_size: Vec2,
    /// Narrowest box, texels.
    pub min_kernel: f32,
    /// Widest box, texels.
    pub max_width: f32,
}

/// The push-constant block of `glsl/cssm/prepare.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CssmPreparePush {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map width and height.
    pub map_size: i32,
    /// Light view near plane.
    pub near: f32,
    /// Light view far plane.
    pub far: f32,
    /// 1 for a perspective light view.
    pub perspective: i32,
    /// Padding to the block's size.
    pub pad: [i32; 2],
}

/// Fractional bits of the tables for boxes up to `max_width` texels: windows of
/// (⌈max_width⌉ + 2)² texels of value ≤ 1 must sum below 2^32 to stay exact; at most 16.
pub fn fixed_bits(max_width: f64) -> u32 {
    let texels = (max_width.ceil() + 2.0).powi(2);
    let bits = (4_294_967_295.0 / texels).log2().floor();
    bits.clamp(1.0, 16.0) as u32
}

/// The damped weights σ_k·2/c_k, k = 1..M (`csm`'s series).
pub fn weights(terms: u32, damping: f64) -> Vec<f32> {
    let m = terms as f64;
    (1..=terms)
        .map(|k| {
            let c = std::f64::consts::PI * (2 * k - 1) as f64;
            ((-damping * (k as f64 / m).powi(2)).exp() * 2.0 / c) as f32
        })
        .collect()
}

impl CssmPush {
    /// The block (term 1, no flags) for `view`, the light's footprint `light_size` and `params`.
    pub fn new(
        view: &LightView,
        view_size: IVec2,
        map_size: u32,
        light_size: Vec2,
        params: &Params,
    ) -> Result<CssmPush> {
        let terms = params.u32("terms")?.clamp(1, csm::MAX_TERMS);
        let damping = params.get("damping")?;
        let series = csm::series(terms, damping);
        let offset = match params.get("offset")? {
            o if o < 0.0 => series.offset,
            o => o,
        };
        let max_width = params.get("max_width")?;
        Ok(CssmPush {
            view_size,
            map_size: map_size as i32,
            pad: 0,
            near: view.near,
            far: view.far,
            perspective: matches!(view.projection, LightProjection::Perspective { .. }) as i32,
            term: 1,
            flags: 0,
            depth_range: params.f32("depth_range")?,
            offset: offset as f32,
            remap: (series.epsilon + REMAP_MARGIN).min(0.499) as f32,
            weight: 0.0,
            scale: (fixed_bits(max_width) as f32).exp2(),
            light_size,
            min_kernel: params.f32("min_kernel")?,
            max_width: max_width as f32,
        })
    }
}

struct Cssm<'a> {
    ctx: Context,
    // Field order is drop order: the tables and sets refer to the images, dropped last.
    /// Every table: z, z sin, z cos, then sin and cos once (rebuilt per term) or per term
    /// (`resident`).
    sats: Vec<Sat<'a>>,
    /// Per term, indices into `sats` of its z, sin, cos, z sin and z cos tables.
    term_tables: Vec<[usize; 5]>,
    resident: bool,
    prepare_set: DescriptorSet,
    encode_set: DescriptorSet,
    /// One lookup set per distinct `term_tables` entry (one, or one per term when resident).
    lookup_sets: Vec<DescriptorSet>,
    prepare: Pipeline,
    encode: Pipeline,
    lookup: Pipeline,
    counters: Buffer,
    prepare_push: CssmPreparePush,
    push: CssmPush,
    weights: Vec<f32>,
    shadow_map: ShadowMap,
    geometry: &'a SceneGeometry,
    _view_images: [Image; 2],
    _images: Vec<Image>,
}

impl<'a> Cssm<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let shadow_map = ShadowMap::new(ctx, *setup.light_view, shadow_map_desc(params)?)?;
        let size = shadow_map.desc.size;
        let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED;
        let desc = ImageDesc::new_2d(vk::Format::R32_SFLOAT, size, size, usage);
        let images = ["z", "sin", "cos", "z sin", "z cos"]
            .iter()
            .map(|n| Image::new(ctx, &format!("cssm {n}"), desc))
            .collect::<Result<Vec<_>>>()?;
        let push = CssmPush::new(
            setup.light_view,
            IVec2::new(setup.view.width as i32, setup.view.height as i32),
            size,
            soft_light(setup.light, setup.light_view, size)?.size,
            params,
        )?;
        let precision = SatPrecision::U32Fixed(push.scale.log2() as u32);
        let terms = params.u32("terms")?.clamp(1, csm::MAX_TERMS) as usize;
        let resident = params.u32("resident")? == 1;
        // Sources of the tables, in `sats` order: z, z sin, z cos, then (sin, cos) once or per
        // term; `images` is [z, sin, cos, z sin, z cos].
        let copies = if resident { terms } else { 1 };
        let sources: Vec<usize> = [0, 3, 4]
            .into_iter()
            .chain((0..copies).flat_map(|_| [1, 2]))
            .collect();
        let term_tables: Vec<[usize; 5]> = (0..terms)
            .map(|k| {
                let pair = 3 + 2 * if resident { k } else { 0 };
                [0, pair, pair + 1, 1, 2]
            })
            .collect();
        let mut sats = Vec::with_capacity(sources.len());
        for image in sources.iter().map(|&i| &images[i]) {
            // SAFETY: `Sat` borrows its source only to tie it to the image's life (its
            // descriptor sets name the image). The images live in the Vec's heap buffer, which
            // moves of `Cssm` do not move and which is never pushed to (no reallocation), and
            // `_images` is the last field, dropped after everything that refers to them (as
            // `savsm` does with boxes).
            let source: &'a Image = unsafe { &*(image as *const Image) };
            let sat = Sat::new(ctx, source, precision)?;
            if sat.bands().len() != 1 {
                return Err(Error::Unsupported {
                    device: ctx.info().name.clone(),
                    feature: format!(
                        "cssm at map size {size}: a table must fit one storage-buffer binding"
                    ),
                });
            }
            sats.push(sat);
        }
        let view_usage = vk::ImageUsageFlags::STORAGE;
        let (w, h) = (setup.view.width, setup.view.height);
        let view_desc = ImageDesc::new_2d(vk::Format::R32G32B32A32_SFLOAT, w, h, view_usage);
        let view_images = [
            Image::new(ctx, "cssm coords", view_desc)?,
            Image::new(ctx, "cssm state", view_desc)?,
        ];
        let prepare = Pipeline::compute(ctx, "cssm/prepare.comp")?;
        let encode = Pipeline::compute(ctx, "cssm/encode.comp")?;
        let lookup = Pipeline::compute(ctx, "cssm/lookup.comp")?;
        let counters = Buffer::storage(ctx, "cssm counters", (COUNTER_NAMES.len() * 4) as u64)?;
        let prepare_set = DescriptorSet::new(
            ctx,
            &prepare,
            &[
                Binding::Image(setup.receivers),
                Binding::Image(&view_images[0]),
            ],
        )?;
        let mut bindings = vec![Binding::Sampled(&shadow_map.depth, &shadow_map.sampler)];
        bindings.extend(images.iter().map(Binding::Image));
        let encode_set = DescriptorSet::new(ctx, &encode, &bindings)?;
        let bindings = [
            Binding::Image(&view_images[0]),
            Binding::Image(&view_images[1]),
            Binding::Image(setup.visibility),
            Binding::Buffer(&counters),
        ];
        let lookup_sets = term_tables[..copies]
            .iter()
            .map(|tables| {
                let mut b = bindings.to_vec();
                b.extend(tables.iter().map(|&t| Binding::Buffer(&sats[t].bands()[0])));
                DescriptorSet::new(ctx, &lookup, &b)
            })
            .collect::<Result<Vec<_>>>()?;
        let view = setup.light_view;
        let prepare_push = CssmPreparePush {
            light_view_proj: view.view_proj,
            view_size: push.view_size,
            map_size: size as i32,
            near: view.near,
            far: view.far,
            perspective: push.perspective,
            pad: [0; 2],
        };
        Ok(Cssm {
            ctx: ctx.clone(),
            sats,
            term_tables,
            resident,
            prepare_set,
            encode_set,
            lookup_sets,
            prepare,
            encode,
            lookup,
            counters,
            prepare_push,
            push,
            weights: weights(terms as u32, params.get("damping")?),
            shadow_map,
            geometry: setup.geometry,
            _view_images: view_images,
            _images: images,
        })
    }

    /// One term of one loop: encode, the tables it needs, the lookup.
    fn record_term(&self, rec: &mut Recorder<'_>, index: usize, filter: bool) -> Result<()> {
        let size = self.shadow_map.desc.size;
        let terms = self.weights.len();
        let flags = if filter { FLAG_FILTER } else { 0 }
            | if index == 0 { FLAG_FIRST } else { 0 }
            | if index + 1 == terms { FLAG_LAST } else { 0 };
        let push = CssmPush {
            term: index as i32 + 1,
            flags,
            weight: self.weights[index],
            ..self.push
        };
        // The search needs z (once) and all four bases; the filter only sin and cos, which
        // resident tables still hold from the search.
        let tables = &self.term_tables[index];
        let build = match (filter, index) {
            (false, 0) => &tables[..],
            (false, _) => &tables[1..],
            (true, _) if self.resident => &tables[..0],
            (true, _) => &tables[1..3],
        };
        if !build.is_empty() {
            rec.dispatch(&self.encode, &self.encode_set, &push, [size, size, 1])?;
        }
        for &t in build {
            self.sats[t].record(rec)?;
        }
        let view = self.push.view_size;
        let threads = [view.x as u32, view.y as u32, 1];
        let set = &self.lookup_sets[index.min(self.lookup_sets.len() - 1)];
        rec.dispatch(&self.lookup, set, &push, threads)
    }
}

impl Technique for Cssm<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        let view = self.push.view_size;
        rec.begin_pass("cssm-search")?;
        rec.dispatch(
            &self.prepare,
            &self.prepare_set,
            &self.prepare_push,
            [view.x as u32, view.y as u32, 1],
        )?;
        for k in 0..self.weights.len() {
            self.record_term(rec, k, false)?;
        }
        rec.begin_pass("cssm-filter")?;
        rec.fill(&self.counters, 0);
        for k in 0..self.weights.len() {
            self.record_term(rec, k, true)?;
        }
        rec.end_pass();
        Ok(())
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let mut out = super::read_counters(&self.ctx, &self.counters, &COUNTER_NAMES)?;
        out.push(("terms".to_string(), self.weights.len() as u64));
        Ok(out)
    }

    fn shadow_map(&self) -> Option<&ShadowMap> {
        Some(&self.shadow_map)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader_interface;
    use std::mem::size_of;

    #[test]
    fn push_blocks_match_the_shaders() {
        assert_eq!(size_of::<CssmPush>(), 72);
        assert_eq!(size_of::<CssmPreparePush>(), 96);
        for shader in ["cssm/encode.comp", "cssm/lookup.comp"] {
            let declared = shader_interface(shader).expect("embedded").1;
            assert_eq!(declared.push_constant_size as usize, size_of::<CssmPush>());
        }
        let declared = shader_interface("cssm/prepare.comp").expect("embedded").1;
        assert_eq!(
            declared.push_constant_size as usize,
            size_of::<CssmPreparePush>()
        );
    }

    /// Windows of (⌈w⌉ + 2)² texels at 2^bits each stay below 2^32.
    #[test]
    fn fixed_bits_keep_windows_exact() {
        assert_eq!(fixed_bits(128.0), 16);
        assert_eq!(fixed_bits(1024.0), 11);
        for w in [1.0, 64.0, 200.0, 700.0, 1024.0] {
            let bits = fixed_bits(w);
            assert!((w.ceil() + 2.0).powi(2) * (bits as f64).exp2() < 4_294_967_296.0);
        }
    }
}
