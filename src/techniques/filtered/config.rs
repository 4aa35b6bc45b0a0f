//! The filtered techniques' shared configuration: which formula the shaders apply, the
//! resolved knobs ([`FilterConfig`], from each technique's own knobs and the common ones), and
//! the push constants every pass of `glsl/filtered/` reads.

use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Mat4, Vec4};

use super::{csm, esm, evsm, msm, vsm, MAX_RADIUS};
use crate::error::{Error, Result};
use crate::passes::{LightProjection, LightView};
use crate::techniques::{Knob, KnobDefault, Params, SHADOW_MAP_KNOBS};

/// Which formula the shaders apply (`MODE_*` in `filtered.glsl`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Variance shadow maps.
    Vsm = 0,
    /// Exponential shadow maps (log-space filtering).
    Esm = 1,
    /// Exponential variance shadow maps.
    Evsm = 2,
    /// Moment shadow maps (Hamburger 4MSM).
    Msm = 3,
    /// Convolution shadow maps.
    Csm = 4,
}

/// A technique's resolved filtering setup: what the push constants carry besides the views.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterConfig {
    /// The formula.
    pub mode: Mode,
    /// Blur radius in texels (0: no blur).
    pub radius: u32,
    /// Box instead of Gaussian.
    pub box_filter: bool,
    /// EVSM: 2 or 4 components; otherwise unused.
    pub components: u32,
    /// CSM: the number of terms M; otherwise 0.
    pub terms: u32,
    /// The technique's constants, in the order `filtered.glsl` documents.
    pub params: [f32; 4],
}

impl FilterConfig {
    /// The channels of its basis each texel needs: ESM's c·z alone, VSM's two moments, EVSM's
    /// `components`, MSM's four, CSM's sin and cos of two terms a group (one term: two).
    pub fn used_channels(&self) -> u32 {
        match self.mode {
            Mode::Esm => 1,
            Mode::Vsm => 2,
            Mode::Evsm => self.components,
            Mode::Msm => 4,
            Mode::Csm => {
                if self.terms <= 1 {
                    2
                } else {
                    4
                }
            }
        }
    }

    /// The channels the filtered image stores on a device: [`FilterConfig::used_channels`] with
    /// `pack` on, except that two channels need `shaderStorageImageExtendedFormats` and
    /// `R32G32_SFLOAT` storage (else four); always four with `pack` off.
    pub fn stored_channels(&self, pack: bool, info: &crate::gpu::DeviceInfo) -> u32 {
        match self.used_channels() {
            _ if !pack => 4,
            2 if !(info.storage_image_extended_formats && info.rg32f_storage) => 4,
            n => n,
        }
    }

    /// Dispatch groups of the encode–blur–reconstruct chain: ⌈M/2⌉ for CSM, else 1.
    pub fn groups(&self) -> u32 {
        if self.mode == Mode::Csm {
            self.terms.div_ceil(2).max(1)
        } else {
            1
        }
    }
}

/// The push-constant block of `glsl/filtered/filtered.glsl`, shared by its three shaders.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct FilteredPush {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map width and height.
    pub map_size: i32,
    /// [`Mode`] as an integer.
    pub mode: i32,
    /// Light view near plane.
    pub near: f32,
    /// Light view far plane.
    pub far: f32,
    /// 1 for a perspective light view (depth is linearised), 0 for orthographic.
    pub perspective: i32,
    /// Blur radius in texels.
    pub radius: i32,
    /// 1: box blur; 0: Gaussian.
    pub box_filter: i32,
    /// EVSM: components; CSM: the 1-based index of this group's first term.
    pub channel_info: i32,
    /// CSM: the number of terms M.
    pub terms: i32,
    /// `FLAG_FIRST` (1) and `FLAG_LAST` (2): where this dispatch sits in the CSM group loop.
    pub flags: i32,
    /// The technique's constants ([`FilterConfig::params`]).
    pub params: Vec4,
}

/// `FLAG_FIRST | FLAG_LAST`: a single-group technique.
pub const FLAGS_ONLY_GROUP: i32 = 3;

/// The push constants of group `group` (0-based) of `config` for `view`.
pub fn push_constants(
    config: &FilterConfig,
    view: &LightView,
    view_size: IVec2,
    map_size: u32,
    group: u32,
) -> FilteredPush {
    let groups = config.groups();
    let first = (group == 0) as i32;
    let last = ((group + 1 >= groups) as i32) << 1;
    FilteredPush {
        light_view_proj: view.view_proj,
        view_size,
        map_size: map_size as i32,
        mode: config.mode as i32,
        near: view.near,
        far: view.far,
        perspective: matches!(view.projection, LightProjection::Perspective { .. }) as i32,
        radius: config.radius.min(MAX_RADIUS) as i32,
        box_filter: config.box_filter as i32,
        channel_info: match config.mode {
            Mode::Csm => (2 * group + 1) as i32,
            _ => config.components as i32,
        },
        terms: config.terms as i32,
        flags: first | last,
        params: Vec4::from_array(config.params),
    }
}

/// `filter_radius`: the blur's reach.
pub const FILTER_RADIUS: Knob = Knob {
    name: "filter_radius",
    summary: "blur radius in texels (0: none; Gaussian sigma = radius/2, box width 2r+1)",
    default: KnobDefault::Value(2.0),
    min: 0.0,
    max: MAX_RADIUS as f64,
    integer: true,
    names: &[],
};

/// `filter_shape`: Gaussian or box.
pub const FILTER_SHAPE: Knob = Knob {
    name: "filter_shape",
    summary: "0: Gaussian; 1: box (with the bilinear fetch, pcf's window at kernel = 2r+1)",
    default: KnobDefault::Value(0.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &[],
};

/// `pack_channels`: store and filter only the channels the technique's basis uses.
pub const PACK_CHANNELS: Knob = Knob {
    name: "pack_channels",
    summary: "1: the filtered image holds only the channels the technique uses (ESM 1, VSM and \
              2-component EVSM 2; same output, counted as skipped_channels); 0: always four",
    default: KnobDefault::Value(1.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &[],
};

/// `blur_layout`: how the encode and blur passes are laid out ([`BlurLayout`](super::BlurLayout)).
pub const BLUR_LAYOUT: Knob = Knob {
    name: "blur_layout",
    summary: "auto: staged on a device that runs workgroups on CPU threads, else shared; shared: \
              rows in workgroup shared memory (GPUs); staged: a pass a direction, each writing a \
              buffer copied into the map (same texels)",
    default: KnobDefault::Value(0.0),
    min: 0.0,
    max: 2.0,
    integer: true,
    names: &["auto", "shared", "staged"],
};

/// The knobs every filtered technique starts with: the shadow map's, then the blur's, then the
/// channel packing and the passes' layout.
pub const COMMON_KNOBS: [Knob; 8] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    FILTER_RADIUS,
    FILTER_SHAPE,
    PACK_CHANNELS,
    BLUR_LAYOUT,
];

/// A [`FilterConfig`] with the blur knobs read and everything else zero.
pub(super) fn base_config(mode: Mode, params: &Params) -> Result<FilterConfig> {
    Ok(FilterConfig {
        mode,
        radius: params.u32("filter_radius")?.min(MAX_RADIUS),
        box_filter: params.u32("filter_shape")? == 1,
        components: 4,
        terms: 0,
        params: [0.0; 4],
    })
}

/// The resolved setup of filtered technique `name` (for tests and CPU twins).
pub fn config(name: &str, params: &Params) -> Result<FilterConfig> {
    match name {
        "vsm" => vsm::config(params),
        "esm" => esm::config(params),
        "evsm" => evsm::config(params),
        "msm" => msm::config(params),
        "csm" => csm::config(params),
        other => Err(Error::Parameter {
            technique: other.to_string(),
            message: "not a filtered shadow-map technique".into(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    #[test]
    fn push_layout_is_the_documented_one() {
        assert_eq!(offset_of!(FilteredPush, light_view_proj), 0);
        assert_eq!(offset_of!(FilteredPush, view_size), 64);
        assert_eq!(offset_of!(FilteredPush, map_size), 72);
        assert_eq!(offset_of!(FilteredPush, mode), 76);
        assert_eq!(offset_of!(FilteredPush, near), 80);
        assert_eq!(offset_of!(FilteredPush, far), 84);
        assert_eq!(offset_of!(FilteredPush, perspective), 88);
        assert_eq!(offset_of!(FilteredPush, radius), 92);
        assert_eq!(offset_of!(FilteredPush, box_filter), 96);
        assert_eq!(offset_of!(FilteredPush, channel_info), 100);
        assert_eq!(offset_of!(FilteredPush, terms), 104);
        assert_eq!(offset_of!(FilteredPush, flags), 108);
        assert_eq!(offset_of!(FilteredPush, params), 112);
        // 128 bytes: the smallest maxPushConstantsSize Vulkan guarantees.
        assert_eq!(size_of::<FilteredPush>(), 128);
        // Every filtered shader's block against these fields, member by member:
        // tests/shaders_push.rs (every_push_struct_matches_its_reflected_block_member_by_member).
    }

    #[test]
    fn groups_and_flags_cover_the_terms() {
        let view = LightView {
            view: Mat4::IDENTITY,
            proj: Mat4::IDENTITY,
            view_proj: Mat4::IDENTITY,
            projection: LightProjection::Orthographic { half_extent: 1.0 },
            near: 0.0,
            far: 1.0,
            origin: glam::Vec3::ZERO,
            direction: glam::Vec3::NEG_Z,
        };
        let mut config = FilterConfig {
            mode: Mode::Csm,
            radius: 1,
            box_filter: false,
            components: 4,
            terms: 5,
            params: [0.5, 0.0, 0.0, 1.0],
        };
        assert_eq!(config.groups(), 3);
        let flags: Vec<_> = (0..3)
            .map(|g| push_constants(&config, &view, IVec2::ONE, 16, g))
            .map(|p| (p.channel_info, p.flags))
            .collect();
        assert_eq!(flags, vec![(1, 1), (3, 0), (5, 2)]);
        config.mode = Mode::Vsm;
        let p = push_constants(&config, &view, IVec2::ONE, 16, 0);
        assert_eq!((p.flags, p.perspective), (FLAGS_ONLY_GROUP, 0));
    }
}
