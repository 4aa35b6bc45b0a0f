//! Typed technique descriptions for library users: [`TechniqueKind`] names a technique without a
//! string, and [`TechniqueDesc`] sets its knobs with typed values, each checked when it is set
//! against the technique's knob table (name, integer or real, range, the names of an enumerated
//! knob) so a mistake surfaces where it is made, with the knobs the technique has. The CLI and
//! the bench keep the string map ([`crate::Engine::renderer`]); a description resolves to the
//! same map, so both paths share one resolution against the scene's defaults.

use std::collections::BTreeMap;

use crate::error::{Error, Result};
use crate::techniques::{self, TechniqueInfo};

macro_rules! technique_kinds {
    ($($variant:ident => $name:literal: $doc:literal,)*) => {
        /// Every technique penumbra implements (see `penumbra techniques` for each one's knobs).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[non_exhaustive]
        pub enum TechniqueKind {
            $(#[doc = $doc] $variant,)*
        }

        impl TechniqueKind {
            /// Every kind, in the registry's order.
            pub const ALL: &'static [TechniqueKind] = &[$(TechniqueKind::$variant,)*];

            /// Its registered (CLI) name.
            pub fn name(self) -> &'static str {
                match self {
                    $(TechniqueKind::$variant => $name,)*
                }
            }
        }
    };
}

technique_kinds! {
    Hard => "hard": "Standard shadow mapping: one nearest-texel depth test from the light centre.",
    Pcf => "pcf": "Percentage-closer filtering over a fixed kernel of bilinear tests.",
    Lispsm => "lispsm": "Light-space perspective shadow map: one map warped along the view direction.",
    AverageMaps => "average-maps": "Brute-force soft shadows: the average of hard maps from light samples.",
    Reference => "reference": "Ground truth: shadow rays through a BVH to stratified light samples.",
    ReferenceSingleLayer => "reference-single-layer": "Ground truth with only the occluders seen from the light centre.",
    PcfPoisson => "pcf-poisson": "PCF over a rotated Poisson disk.",
    PcfCoverage => "pcf-coverage": "Exact texel-coverage box PCF, continuous in the kernel width.",
    Vsm => "vsm": "Variance shadow maps.",
    Esm => "esm": "Exponential shadow maps.",
    Evsm => "evsm": "Exponential variance shadow maps.",
    Msm => "msm": "Moment shadow maps: four blurred moments, Hamburger lower bound.",
    Csm => "csm": "Convolution shadow maps (Fourier basis).",
    Savsm => "savsm": "Summed-area variance shadow maps.",
    Pcss => "pcss": "Percentage-closer soft shadows: blocker search, exact-coverage filter.",
    Cssm => "cssm": "Convolution soft shadows: PCSS from a Fourier basis in summed-area tables.",
    Vssm => "vssm": "Variance soft shadow mapping: blocker depth and filter from moment SATs.",
    Essm => "essm": "Exponential soft shadow mapping: blocker depth and ESM over the footprint.",
    Rmsm => "rmsm": "Resolution-matched virtual shadow map: GPU page requests, pool, page draws.",
    Pvssm => "pvssm": "Predicted virtual soft shadow maps: exact PCSS filtering on predicted pages.",
    Izb => "izb": "Irregular z-buffer: exact hard shadows at the view samples.",
    IzbSoft => "izb-soft": "Irregular z-buffer with a light-sample bitmask per view sample.",
    Cascades => "cascades": "Cascaded shadow maps: z-partitions, one map each, blended at the borders.",
    Atty => "atty": "Soft shadow maps: occluder micropatches summed into a light-space map.",
    Bitmask => "bitmask": "Back-projected micropatches OR-ed into light-sample bitmasks.",
}

impl TechniqueKind {
    /// The kind registered under `name`.
    pub fn from_name(name: &str) -> Result<TechniqueKind> {
        TechniqueKind::ALL
            .iter()
            .copied()
            .find(|k| k.name() == name)
            .ok_or_else(|| Error::UnknownTechnique {
                name: name.to_string(),
                known: TechniqueKind::ALL
                    .iter()
                    .map(|k| k.name().to_string())
                    .collect(),
            })
    }

    /// Its registry entry (summary, knobs, constructor).
    pub fn info(self) -> Result<&'static TechniqueInfo> {
        techniques::find(self.name())
    }
}

impl std::fmt::Display for TechniqueKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A typed knob value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KnobValue {
    /// An integer (a size, a count, a 0/1 switch).
    Int(i64),
    /// A real number.
    Real(f64),
    /// One of an enumerated knob's names (e.g. `fit = "scene"`).
    Choice(&'static str),
}

impl From<i64> for KnobValue {
    fn from(v: i64) -> Self {
        KnobValue::Int(v)
    }
}

impl From<u32> for KnobValue {
    fn from(v: u32) -> Self {
        KnobValue::Int(i64::from(v))
    }
}

impl From<f64> for KnobValue {
    fn from(v: f64) -> Self {
        KnobValue::Real(v)
    }
}

impl From<f32> for KnobValue {
    fn from(v: f32) -> Self {
        KnobValue::Real(f64::from(v))
    }
}

impl From<bool> for KnobValue {
    fn from(v: bool) -> Self {
        KnobValue::Int(i64::from(v))
    }
}

impl From<&'static str> for KnobValue {
    fn from(v: &'static str) -> Self {
        KnobValue::Choice(v)
    }
}

/// An enumerated knob's value as a Rust enum: the knob it sets and the name each variant stands
/// for. A test holds every enum to the knob tables (same names, same order) of every technique
/// that has the knob.
pub trait KnobChoice: Copy + 'static {
    /// The knob it sets.
    const KNOB: &'static str;
    /// Every value, in the knob's order (the index is the knob's number).
    const ALL: &'static [Self];
    /// The name the knob table gives this value.
    fn name(self) -> &'static str;
}

macro_rules! knob_choices {
    ($(
        $(#[doc = $doc:literal])*
        $ty:ident for $knob:literal { $($(#[doc = $vdoc:literal])* $variant:ident => $name:literal,)* }
    )*) => {$(
        $(#[doc = $doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum $ty {
            $($(#[doc = $vdoc])* $variant,)*
        }

        impl KnobChoice for $ty {
            const KNOB: &'static str = $knob;
            const ALL: &'static [$ty] = &[$($ty::$variant,)*];
            fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name,)*
                }
            }
        }

        impl From<$ty> for KnobValue {
            fn from(v: $ty) -> KnobValue {
                KnobValue::Choice(v.name())
            }
        }
    )*};
}

knob_choices! {
    /// `fit` (every shadow-map technique but the per-light-sample ones): what the light view is
    /// fitted to.
    Fit for "fit" {
        /// The scene's bounding box.
        Scene => "scene",
        /// The view samples and the casters between them and the light.
        View => "view",
    }
    /// `filter` of `lispsm` and `cascades`: the lookup.
    LookupFilter for "filter" {
        /// One nearest-texel depth test.
        Hard => "hard",
        /// A box of bilinear tests.
        Pcf => "pcf",
    }
    /// `filter` of `rmsm`: how a page texel is read.
    PageFilter for "filter" {
        /// The nearest texel.
        Nearest => "nearest",
        /// Bilinear depth tests.
        Bilinear => "bilinear",
    }
    /// `skip` of `pcss`: the min/max structure that classifies regions first.
    PcssSkip for "skip" {
        /// No classification.
        Off => "off",
        /// An N-buffer (exact).
        NBuffer => "nbuffer",
        /// A min/max pyramid (a superset; cheaper to build).
        Pyramid => "pyramid",
    }
    /// `skip` of `atty` and `bitmask`: an N-buffer classification first.
    NBufferSkip for "skip" {
        /// No classification.
        Off => "off",
        /// Classify by an N-buffer.
        NBuffer => "nbuffer",
    }
    /// `skip` of `pvssm`: the coarse look before the blocker search.
    PvssmSkip for "skip" {
        /// No coarse look.
        Off => "off",
        /// Decide lit samples from a coarse look first.
        Coarse => "coarse",
    }
    /// `split_regions` of `vssm`: which regions are split into sub-regions.
    SplitRegions for "split_regions" {
        /// Only where Chebyshev does not apply (the mean not in front of the receiver): the
        /// paper's rule.
        Leaks => "leaks",
        /// Every region neither all lit nor all umbra.
        Mixed => "mixed",
    }
    /// `rho` of `pvssm`: the perceptual metric that predicts the page resolution.
    RhoMode for "rho" {
        /// The user study's dynamic-occluder metric.
        Dynamic => "dynamic",
        /// The static (cubic) metric.
        Static => "static",
    }
    /// `blocker_depth` of `pvssm` and `pcss`: which blockers z_avg averages.
    BlockerDepth for "blocker_depth" {
        /// Every blocker cell of the region.
        Average => "average",
        /// The silhouette's cells (beside a cell that does not block).
        Silhouette => "silhouette",
    }
    /// `blocker_distance` of `pvssm`: where a blocking cell's distance, for z_avg, is read.
    BlockerDistance for "blocker_distance" {
        /// The conservative map's minimum: the caster's nearest point over the cell.
        Nearest => "nearest",
        /// The centre-depth map: the caster's plane at the cell's centre.
        Centre => "centre",
    }
    /// `lit_flag` of `pvssm`: which blocker-free search decides a sample lit.
    LitFlag for "lit_flag" {
        /// No low-res cell nearer than the receiver plane's lowest depth over it (the search's
        /// own test).
        Search => "search",
        /// Nor than its highest: nothing the filter's texels could find.
        Conservative => "conservative",
    }
    /// `page_raster` of `rmsm` and `pvssm`: what draws the pages' casters.
    PageRasterChoice for "page_raster" {
        /// Compute where workgroups run on CPU threads, the rasterizer otherwise.
        Auto => "auto",
        /// The rasterizer, clipped to each page's slot.
        Graphics => "graphics",
        /// One compute invocation per binned triangle (large ones left to the rasterizer).
        Compute => "compute",
    }
    /// `partition` of `cascades`: where the depth range is split.
    Partition for "partition" {
        /// The practical split (with `lambda`).
        Pssm => "pssm",
        /// Splits and windows fitted to the view samples' depth histogram.
        Sdsm => "sdsm",
        /// Uniform splits.
        Uniform => "uniform",
        /// Logarithmic splits.
        Log => "log",
    }
    /// `combine` of `bitmask`: how micropatches combine.
    Combine for "combine" {
        /// OR the patches' light-sample masks.
        Bitmask => "bitmask",
        /// Sum their hidden areas (over-darkens where they overlap).
        Add => "add",
    }
    /// `moments_layout` of `vssm` and `savsm`: how their moments pass writes (the same texels
    /// either way).
    MomentsLayoutChoice for "moments_layout" {
        /// Staged where workgroups run on CPU threads and the map fits a buffer binding.
        Auto => "auto",
        /// Stores into the moment images (GPUs).
        Image => "image",
        /// Stores into buffers copied into the images.
        Staged => "staged",
    }
    /// `blur_layout` of the filtered techniques (`vsm`, `esm`, `evsm`, `msm`, `csm`): how the
    /// encode and blur passes are laid out (the same texels either way).
    BlurLayoutChoice for "blur_layout" {
        /// Staged where workgroups run on CPU threads and the device can stage, shared otherwise.
        Auto => "auto",
        /// Rows in workgroup shared memory (GPUs).
        Shared => "shared",
        /// A pass a direction, each writing a buffer copied into the filtered image.
        Staged => "staged",
    }
}

/// A technique and the knobs set on it; unset knobs take their defaults (the technique's or the
/// scene's) when a renderer is built.
#[derive(Clone, Debug, PartialEq)]
pub struct TechniqueDesc {
    kind: TechniqueKind,
    overrides: BTreeMap<String, String>,
}

impl TechniqueDesc {
    /// `kind` with every knob at its default.
    pub fn new(kind: TechniqueKind) -> TechniqueDesc {
        TechniqueDesc {
            kind,
            overrides: BTreeMap::new(),
        }
    }

    /// Sets knob `name`, checked now by the same resolution the CLI's `key=value` goes through:
    /// an unknown knob, a fraction for an integer knob, a value out of range or a name an
    /// enumerated knob does not have is an [`Error::Parameter`] naming the knob and what it
    /// accepts.
    pub fn with(mut self, name: &str, value: impl Into<KnobValue>) -> Result<TechniqueDesc> {
        let info = self.kind.info()?;
        let text = match value.into() {
            KnobValue::Int(v) => v.to_string(),
            // `{:?}` prints the shortest text that reads back as the same f64.
            KnobValue::Real(v) => format!("{v:?}"),
            KnobValue::Choice(choice) => choice.to_string(),
        };
        // The CLI's resolution checks it (name, number or named value, range, integer), with
        // the default scene standing in for the one the renderer will be built on.
        let single = BTreeMap::from([(name.to_string(), text)]);
        let resolved = info.params(&single, &crate::scene::SceneDefaults::default())?;
        let v = resolved.get(name)?;
        let integer = info.all_knobs().iter().any(|k| k.name == name && k.integer);
        let text = if integer {
            format!("{}", v as i64)
        } else {
            format!("{v:?}")
        };
        self.overrides.insert(name.to_string(), text);
        Ok(self)
    }

    /// Sets an enumerated knob from its Rust enum (e.g. `.choose(PcssSkip::NBuffer)`), checked
    /// like [`TechniqueDesc::with`]: a technique without the knob, or without that value of it,
    /// is refused.
    pub fn choose<C: KnobChoice>(self, choice: C) -> Result<TechniqueDesc>
    where
        KnobValue: From<C>,
    {
        self.with(C::KNOB, choice)
    }

    /// The technique.
    pub fn kind(&self) -> TechniqueKind {
        self.kind
    }

    /// The knobs set, as the knob → text map the CLI uses.
    pub fn overrides(&self) -> &BTreeMap<String, String> {
        &self.overrides
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (knob, names) of every enum.
    fn enums() -> Vec<(&'static str, Vec<&'static str>)> {
        fn names<C: KnobChoice>() -> (&'static str, Vec<&'static str>) {
            (C::KNOB, C::ALL.iter().map(|c| c.name()).collect())
        }
        vec![
            names::<Fit>(),
            names::<LookupFilter>(),
            names::<PageFilter>(),
            names::<PcssSkip>(),
            names::<NBufferSkip>(),
            names::<PvssmSkip>(),
            names::<SplitRegions>(),
            names::<RhoMode>(),
            names::<BlockerDepth>(),
            names::<BlockerDistance>(),
            names::<LitFlag>(),
            names::<PageRasterChoice>(),
            names::<Partition>(),
            names::<Combine>(),
            names::<BlurLayoutChoice>(),
            names::<MomentsLayoutChoice>(),
        ]
    }

    #[test]
    fn every_enumerated_knob_has_an_enum_with_its_names_in_order() {
        let enums = enums();
        for info in techniques::registry() {
            for knob in info.all_knobs().iter().filter(|k| !k.names.is_empty()) {
                assert!(
                    enums
                        .iter()
                        .any(|(k, n)| *k == knob.name && n.as_slice() == knob.names),
                    "{}: knob {} {:?} has no enum",
                    info.name,
                    knob.name,
                    knob.names
                );
            }
        }
        // And no enum is orphaned: each matches some technique's knob.
        for (knob, names) in &enums {
            assert!(
                techniques::registry().iter().any(|t| t
                    .all_knobs()
                    .iter()
                    .any(|k| k.name == *knob && k.names == names.as_slice())),
                "enum for {knob} {names:?} matches no technique"
            );
        }
    }

    #[test]
    fn enums_set_their_knob_and_a_foreign_value_is_refused() {
        let d = TechniqueDesc::new(TechniqueKind::Pcss)
            .choose(PcssSkip::NBuffer)
            .expect("pcss has skip = nbuffer")
            .choose(Fit::Scene)
            .expect("fit");
        assert_eq!(d.overrides()["skip"], "1");
        assert_eq!(d.overrides()["fit"], "0");
        let e = TechniqueDesc::new(TechniqueKind::Pvssm)
            .choose(PcssSkip::Pyramid)
            .expect_err("pvssm's skip has no pyramid");
        assert!(e.to_string().contains("is not one of off, coarse"), "{e}");
        let e = TechniqueDesc::new(TechniqueKind::Hard)
            .choose(Partition::Log)
            .expect_err("hard has no partition");
        assert!(e.to_string().contains("unknown knob 'partition'"), "{e}");
    }

    #[test]
    fn every_registered_technique_has_a_kind_and_back() {
        let registered: Vec<&str> = techniques::registry().iter().map(|t| t.name).collect();
        let kinds: Vec<&str> = TechniqueKind::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(registered, kinds);
        for k in TechniqueKind::ALL {
            assert_eq!(TechniqueKind::from_name(k.name()).expect("known"), *k);
        }
        assert!(matches!(
            TechniqueKind::from_name("pcss2"),
            Err(Error::UnknownTechnique { .. })
        ));
    }

    #[test]
    fn knobs_are_checked_when_set() {
        let d = TechniqueDesc::new(TechniqueKind::Pcss)
            .with("map_size", 256u32)
            .expect("a size")
            .with("fit", "scene")
            .expect("a named choice")
            .with("normal_offset", 0.5)
            .expect("a real");
        assert_eq!(d.overrides()["map_size"], "256");
        assert_eq!(d.overrides()["fit"], "0");
        assert_eq!(d.overrides()["normal_offset"], "0.5");
        let err = |r: Result<TechniqueDesc>| r.expect_err("refused").to_string();
        let e = err(TechniqueDesc::new(TechniqueKind::Pcss).with("map_sise", 256u32));
        assert!(
            e.contains("unknown knob 'map_sise'") && e.contains("map_size"),
            "{e}"
        );
        let e = err(TechniqueDesc::new(TechniqueKind::Pcss).with("map_size", 256.5));
        assert!(e.contains("must be an integer"), "{e}");
        let e = err(TechniqueDesc::new(TechniqueKind::Pcss).with("map_size", 1u32));
        assert!(e.contains("outside [16"), "{e}");
        let e = err(TechniqueDesc::new(TechniqueKind::Pcss).with("fit", "camera"));
        assert!(e.contains("is not one of scene, view"), "{e}");
        let e = err(TechniqueDesc::new(TechniqueKind::Pcss).with("map_size", "big"));
        assert!(e.contains("is not a number"), "{e}");
        let e = err(TechniqueDesc::new(TechniqueKind::Pcss).with("normal_offset", f64::NAN));
        assert!(e.contains("outside"), "{e}");
    }
}
