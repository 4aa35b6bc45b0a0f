//! The filtered (pre-filterable) shadow maps of the book's chapter 5.3: `vsm`, `esm`, `evsm`,
//! `msm` and `csm`, one shared driver with one file per technique for its knobs and constants.
//!
//! Every technique renders the same D32 [`ShadowMap`] (knobs
//! [`SHADOW_MAP_KNOBS`](super::SHADOW_MAP_KNOBS)) and runs three compute passes over it
//! (`glsl/filtered/`):
//!
//! 1. `encode.comp` linearises each depth into z ∈ `[0,1]` between the light view's near and far
//!    planes, encodes it into up to four channels of one storage image (moments, warped
//!    moments, c·z, or Fourier basis values) and blurs each row horizontally — fused, so the D32
//!    map is read once and each texel encoded once per workgroup.
//!
//! **Unused basis channels are skipped** (`pack_channels`, on by default): the image has only
//! the channels the technique's basis uses ([`FilterConfig::used_channels`]) — R32F for ESM's
//! c·z, RG32F for VSM's two moments, two-component EVSM and one-term CSM, RGBA32F otherwise —
//! and each shader has a variant per channel count (`encode_r.comp`, `encode_rg.comp`, ...;
//! bodies in `*_body.glsl`, `CHANNELS` in `filtered.glsl`), so no unused channel is encoded,
//! stored, blurred or fetched: a quarter (ESM) or half (VSM) of the image's memory, and on
//! lavapipe 1.03–1.32× faster (`penumbra bench --suite skipping`, README "Work skipping").
//! RG32F storage needs
//! `shaderStorageImageExtendedFormats`; without it two-channel techniques keep four. The
//! output is the same either way (the used channels see the same arithmetic); counters
//! `channels` and `skipped_channels`.
//! 2. `blur.comp` blurs the columns **in place** (skipped at `filter_radius` 0): a workgroup owns
//!    whole columns and walks down them through a ring of rows in shared memory, writing only rows
//!    it has already read. A ping-pong pair would double the resident image; this keeps it at one
//!    image. The blur is a separable Gaussian (σ = radius/2, taps to ±radius) or, with
//!    `filter_shape = 1`, a box of width 2·radius+1 — the box convolved with the bilinear fetch
//!    is exactly `pcf`'s window at `kernel = 2·radius+1`, so filtered techniques and PCF can be
//!    compared on identical windows. ESM filters c·z in log space (log-sum-exp).
//! 3. `reconstruct.comp` computes each view sample's receiver depth d in the same light view,
//!    fetches the filtered channels bilinearly by hand (depth formats cannot be filtered on
//!    lavapipe, and storage images never are) and applies the technique's formula.
//!
//! Passes 1 and 2 above are the **shared** [`BlurLayout`], for GPUs. On a device that runs
//! workgroups on CPU threads (the `blur_layout` knob's `auto`) they are **staged** instead:
//! `encode_staged.comp` encodes a texel an invocation, then `blur_staged.comp` blurs the rows and
//! then the columns, four outputs an invocation; each pass writes a storage buffer (32 or 64-bit
//! words holding the channels' bits) that a copy moves over the filtered image after it, so the
//! column pass reads and writes the same image without a race and no pass needs shared memory
//! or a barrier. On lavapipe a barrier turns the shader into coroutines over the workgroup's SIMD
//! rows, and an image store is a call that loops over the lanes once per channel; on teapot-rect
//! (2048² map) the encode and blur passes took 112 + 85 → 57 + 32 ms for `vsm`, 141 + 149 →
//! 81 + 48 for `msm`, and `csm`'s terms 619 → 318 ms, the visibility byte-identical (`penumbra
//! render … --set blur_layout=shared|staged`, medians of three frames for `vsm`, one frame for
//! `msm` and `csm`). Both layouts add the same taps in the same order
//! and divide by the same total, so they give the same bits
//! (`tests/filtered_properties.rs::staged_and_shared_blurs_give_the_same_bits`).
//!
//! The filtered map is an image, not a storage buffer: its `maxStorageBufferRange` is 128 MiB on
//! lavapipe, which a buffer of 16 B per texel would hit at 2896² — images go to
//! `maxImageDimension2D`. The staged layout's buffer is bounded the same way, so past it (or
//! without `shaderInt64` past one channel) `auto` takes the shared layout.
//!
//! Timed passes: `light-depth`, `<name>-encode` (encode + horizontal blur), `<name>-blur`
//! (vertical), `<name>-reconstruct`; CSM times its whole group loop as `csm-terms`.
//!
//! Texels outside the map read as the far plane (z = 1) in the blur and the fetch alike, the
//! convention of `shadow_map.glsl`: receivers near the map's edge are lit, as with `pcf`.
//! Receivers outside the light frustum are lit and counted (`outside_light`).
//!
//! `csm` needs 2M basis images. Rather than hold them all, it processes two terms (four
//! channels) at a time — encode, blur, add their contribution into the visibility image — so
//! memory stays at one RGBA32F image whatever M is, and only the M terms asked for are computed.
//!
//! **Memory per shadow-map texel** while running: 4 B (D32) + 4 B per stored channel — 8 B for
//! ESM, 12 B for VSM and two-component EVSM, 20 B for the rest (20 B for all with
//! `pack_channels = 0`) — and in the staged layout 4 B more per stored channel (the buffer). The
//! classic stored sizes (Table 5.1 of the book) are in each technique's module: they are what a
//! renderer that keeps the filtered map would hold.
//!
//! CPU twin: [`crate::cpu::filtered`].

pub mod csm;
pub mod esm;
pub mod evsm;
pub mod msm;
pub mod vsm;

mod config;
use config::base_config;
pub use config::{
    config, push_constants, FilterConfig, FilteredPush, Mode, BLUR_LAYOUT, COMMON_KNOBS,
    FILTER_RADIUS, FILTER_SHAPE, FLAGS_ONLY_GROUP, PACK_CHANNELS,
};

use ash::vk;
use glam::IVec2;

use super::pcf::shadow_map_desc;
use super::{staged_knob, Params, Technique, TechniqueSetup};
use crate::cpu::filtered::COUNTER_NAMES;
use crate::error::Result;
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline, Recorder};
use crate::passes::{SceneGeometry, ShadowMap};

/// The widest blur (`MAX_RADIUS` in `filtered.glsl`: the shared-memory aprons are sized for it).
pub const MAX_RADIUS: u32 = 16;

/// Rows one `encode.comp` workgroup walks through (`ROWS` there).
const ENCODE_ROWS: u32 = 4;

/// Outputs one `blur_staged` invocation makes side by side (`CHAIN` in
/// `glsl/filtered/blur_staged_body.glsl`).
const STAGED_CHAIN: u32 = 4;

/// `FLAG_VERTICAL` in `filtered.glsl`: the staged blur's dispatch along columns.
const FLAG_VERTICAL: i32 = 4;

/// How the filtered map is encoded and blurred (the `blur_layout` knob). Both give the same
/// texels: each output adds its taps in the same order and divides by the same total.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlurLayout {
    /// Workgroups share rows in shared memory: encode fused with the horizontal blur, then the
    /// columns blurred in place through a ring of rows (`encode.comp`, `blur.comp`). For GPUs.
    Shared,
    /// No shared memory or barrier: encode, blur the rows, blur the columns, each pass writing a
    /// storage buffer that a copy moves into the filtered image (`encode_staged.comp`,
    /// `blur_staged.comp`). For devices that run workgroups on CPU threads: on lavapipe a
    /// barrier makes the shader coroutines over the workgroup's SIMD rows, and an image store
    /// costs a call that loops over the lanes once per channel. Needs a map within
    /// `maxStorageBufferRange` and, past one channel, `shaderInt64`.
    Staged,
}

impl BlurLayout {
    /// The layout the `blur_layout` knob asks for on this device for a `size`² map of
    /// `channels` channels: 0 (auto) staged where the device runs workgroups on CPU threads and
    /// can stage, else shared; 1 shared; 2 staged, or an error where the device cannot.
    pub fn choose(ctx: &Context, knob: u32, size: u32, channels: u32) -> Result<BlurLayout> {
        let info = ctx.info();
        let bytes = u64::from(size) * u64::from(size) * u64::from(channels) * 4;
        let range = info.max_storage_buffer_range;
        let can_stage = (channels == 1 || info.int64) && bytes <= u64::from(range);
        let staged = staged_knob(ctx, knob, can_stage, || {
            format!(
                "blur_layout = staged for a {size}² map of {channels} channels (a staging buffer \
                 of {bytes} bytes within maxStorageBufferRange {range}, and shaderInt64 past one \
                 channel)"
            )
        })?;
        Ok(if staged {
            BlurLayout::Staged
        } else {
            BlurLayout::Shared
        })
    }
}

/// The format of the filtered image with all four channels.
pub const FILTERED_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

/// The format of a filtered image of `channels` (1, 2 or 4) channels, and the suffix of its
/// shader variants (`encode_r.comp`, `encode_rg.comp`, `encode.comp`, ...).
pub fn filtered_format(channels: u32) -> (vk::Format, &'static str) {
    match channels {
        1 => (vk::Format::R32_SFLOAT, "_r"),
        2 => (vk::Format::R32G32_SFLOAT, "_rg"),
        _ => (FILTERED_FORMAT, ""),
    }
}

/// A filtered technique instance: the map, the filtered image and the three pipelines.
struct Filtered<'a> {
    ctx: Context,
    name: &'static str,
    config: FilterConfig,
    /// Channels the filtered image stores (of the four the shaders could write).
    channels: u32,
    shadow_map: ShadowMap,
    filtered: Image,
    passes: FilterPasses,
    reconstruct: Pipeline,
    reconstruct_set: DescriptorSet,
    counters: Buffer,
    view_size: IVec2,
    geometry: &'a SceneGeometry,
}

/// The encode and blur passes in their [`BlurLayout`]: the shared layout's `encode.comp` and
/// `blur.comp` writing the filtered image, or the staged layout's `encode_staged.comp` and
/// `blur_staged.comp` writing `staging`, which is copied over the image after each dispatch.
struct FilterPasses {
    encode: Pipeline,
    blur: Pipeline,
    encode_set: DescriptorSet,
    blur_set: DescriptorSet,
    staging: Option<Buffer>,
}

/// Builds filtered technique `name` with `config`.
pub fn create<'a>(
    setup: &TechniqueSetup<'a>,
    params: &Params,
    name: &'static str,
    config: FilterConfig,
) -> Result<Box<dyn Technique + 'a>> {
    let ctx = setup.ctx;
    let shadow_map = ShadowMap::new(ctx, *setup.light_view, shadow_map_desc(params)?)?;
    let size = shadow_map.desc.size;
    let channels = config.stored_channels(params.u32("pack_channels")? == 1, ctx.info());
    // One variant of each shader per channel count (the image's format qualifier).
    let (format, suffix) = filtered_format(channels);
    let layout = BlurLayout::choose(ctx, params.u32("blur_layout")?, size, channels)?;
    let filtered = Image::new(
        ctx,
        &format!("{name} filtered map"),
        ImageDesc::new_2d(
            format,
            size,
            size,
            vk::ImageUsageFlags::STORAGE
                | vk::ImageUsageFlags::TRANSFER_SRC
                | vk::ImageUsageFlags::TRANSFER_DST,
        ),
    )?;
    let depth = Binding::Sampled(&shadow_map.depth, &shadow_map.sampler);
    let passes = match layout {
        BlurLayout::Shared => {
            let encode = Pipeline::compute(ctx, &format!("filtered/encode{suffix}.comp"))?;
            let blur = Pipeline::compute(ctx, &format!("filtered/blur{suffix}.comp"))?;
            FilterPasses {
                encode_set: DescriptorSet::new(ctx, &encode, &[depth, Binding::Image(&filtered)])?,
                blur_set: DescriptorSet::new(ctx, &blur, &[Binding::Image(&filtered)])?,
                encode,
                blur,
                staging: None,
            }
        }
        BlurLayout::Staged => {
            let bytes = u64::from(size) * u64::from(size) * u64::from(channels) * 4;
            let staging = Buffer::storage(ctx, &format!("{name} staging"), bytes)?;
            let encode = Pipeline::compute(ctx, &format!("filtered/encode_staged{suffix}.comp"))?;
            let blur = Pipeline::compute(ctx, &format!("filtered/blur_staged{suffix}.comp"))?;
            let written = Binding::Buffer(&staging);
            FilterPasses {
                encode_set: DescriptorSet::new(ctx, &encode, &[depth, written])?,
                blur_set: DescriptorSet::new(ctx, &blur, &[Binding::Image(&filtered), written])?,
                encode,
                blur,
                staging: Some(staging),
            }
        }
    };
    let reconstruct = Pipeline::compute(ctx, &format!("filtered/reconstruct{suffix}.comp"))?;
    let counters = Buffer::storage(
        ctx,
        &format!("{name} counters"),
        (COUNTER_NAMES.len() * 4) as u64,
    )?;
    let reconstruct_set = DescriptorSet::new(
        ctx,
        &reconstruct,
        &[
            Binding::Image(setup.receivers),
            Binding::Image(&filtered),
            Binding::Image(setup.visibility),
            Binding::Buffer(&counters),
        ],
    )?;
    Ok(Box::new(Filtered {
        ctx: ctx.clone(),
        name,
        config,
        channels,
        shadow_map,
        filtered,
        passes,
        reconstruct,
        reconstruct_set,
        counters,
        view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
        geometry: setup.geometry,
    }))
}

impl Filtered<'_> {
    /// Encode + horizontal blur, then the in-place vertical blur, for one group; with `timed`,
    /// each as its own timed pass.
    fn record_filter(
        &self,
        rec: &mut Recorder<'_>,
        push: &FilteredPush,
        timed: bool,
    ) -> Result<()> {
        let size = self.shadow_map.desc.size;
        let blurred = self.config.radius > 0;
        if timed {
            rec.begin_pass(&format!("{}-encode", self.name))?;
        }
        let FilterPasses {
            encode,
            blur,
            encode_set,
            blur_set,
            staging,
        } = &self.passes;
        let Some(staging) = staging else {
            let rows = size.div_ceil(ENCODE_ROWS);
            rec.dispatch(encode, encode_set, push, [size, rows, 1])?;
            if blurred {
                if timed {
                    rec.begin_pass(&format!("{}-blur", self.name))?;
                }
                // One workgroup per strip of columns: local_size.y threads cover it vertically.
                let rows = blur.local_size[1];
                rec.dispatch(blur, blur_set, push, [size, rows, 1])?;
            }
            return Ok(());
        };
        rec.dispatch(encode, encode_set, push, [size, size, 1])?;
        rec.copy_buffer_to_image(staging, &self.filtered);
        if blurred {
            // Rows (in the encode pass's time, as the shared layout fuses them), then columns:
            // CHAIN outputs an invocation across the blur's direction.
            let chains = size.div_ceil(STAGED_CHAIN);
            rec.dispatch(blur, blur_set, push, [size, chains, 1])?;
            rec.copy_buffer_to_image(staging, &self.filtered);
            if timed {
                rec.begin_pass(&format!("{}-blur", self.name))?;
            }
            let columns = FilteredPush {
                flags: push.flags | FLAG_VERTICAL,
                ..*push
            };
            rec.dispatch(blur, blur_set, &columns, [chains, size, 1])?;
            rec.copy_buffer_to_image(staging, &self.filtered);
        }
        Ok(())
    }

    fn record_reconstruct(&self, rec: &mut Recorder<'_>, push: &FilteredPush) -> Result<()> {
        let threads = [self.view_size.x as u32, self.view_size.y as u32, 1];
        rec.dispatch(&self.reconstruct, &self.reconstruct_set, push, threads)
    }
}

impl Technique for Filtered<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        let size = self.shadow_map.desc.size;
        let view = self.shadow_map.view;
        let groups = self.config.groups();
        if groups == 1 {
            let push = push_constants(&self.config, &view, self.view_size, size, 0);
            self.record_filter(rec, &push, true)?;
            rec.begin_pass(&format!("{}-reconstruct", self.name))?;
            rec.fill(&self.counters, 0);
            self.record_reconstruct(rec, &push)?;
        } else {
            // One timed pass for the loop over term groups: its total is the technique's cost.
            rec.begin_pass(&format!("{}-terms", self.name))?;
            rec.fill(&self.counters, 0);
            for group in 0..groups {
                let push = push_constants(&self.config, &view, self.view_size, size, group);
                self.record_filter(rec, &push, false)?;
                self.record_reconstruct(rec, &push)?;
            }
        }
        rec.end_pass();
        Ok(())
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let mut out = crate::techniques::read_counters(&self.ctx, &self.counters, &COUNTER_NAMES)?;
        if self.config.mode == Mode::Csm {
            out.push(("terms".to_string(), self.config.terms as u64));
        }
        // Channels stored and filtered per texel, and those of the four skipped as unused.
        out.push(("channels".to_string(), u64::from(self.channels)));
        out.push(("skipped_channels".to_string(), u64::from(4 - self.channels)));
        Ok(out)
    }

    fn shadow_map(&self) -> Option<&ShadowMap> {
        Some(&self.shadow_map)
    }
}
