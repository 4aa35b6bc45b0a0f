//! The command line's arguments: every subcommand and its flags (clap derive), apart from the
//! code that runs them.

use std::path::PathBuf;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "penumbra",
    version,
    about = "Shadow techniques on Vulkan, measured for time and error"
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub(crate) command: Command,
}

#[derive(clap::Args)]
pub(crate) struct DeviceArgs {
    /// Vulkan device: index or name substring (default: PENUMBRA_DEVICE, else discrete > integrated > CPU).
    #[arg(long)]
    pub(crate) device: Option<String>,
    /// Run without the validation layers (faster; stats.json then reports null validation counts).
    /// With validation on (the default) any validation error or warning fails the command.
    #[arg(long)]
    pub(crate) no_validation: bool,
}

#[derive(clap::Args)]
pub(crate) struct CacheArgs {
    /// Reference cache directory (default: PENUMBRA_CACHE_DIR, XDG_CACHE_HOME/penumbra or ~/.cache/penumbra).
    #[arg(long)]
    pub(crate) cache_dir: Option<PathBuf>,
    /// Do not read or write the reference cache.
    #[arg(long)]
    pub(crate) no_cache: bool,
}

impl CacheArgs {
    pub(crate) fn dir(&self) -> Option<PathBuf> {
        if self.no_cache {
            None
        } else {
            self.cache_dir.clone().or_else(penumbra::cache::default_dir)
        }
    }
}

#[derive(Subcommand)]
pub(crate) enum Command {
    /// Render a scene with one technique and write images and stats.json.
    Render {
        /// A scene file (.toml) or a procedural scene (e.g. `plane-boxes`, `grid:1000000@rect`).
        scene: String,
        /// Technique name (see `penumbra techniques`), or `auto`: the cheapest candidate the
        /// calibration table predicts within `--max-error` (what was picked and why goes to
        /// stats.json's `selection`).
        #[arg(long, short)]
        technique: String,
        /// With `--technique auto`: the largest penumbra MAE allowed.
        #[arg(long)]
        max_error: Option<f64>,
        /// With `--technique auto`: the calibration table (`bench --suite selection` writes one;
        /// default: the bundled lavapipe table, calibration/lavapipe.json).
        #[arg(long)]
        calibration: Option<PathBuf>,
        /// Knob values, `key=value`, repeatable.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output directory (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Timed frames after one warm-up frame; times are medians.
        #[arg(long, default_value_t = 3)]
        frames: u32,
        /// Scale the scene's light as `bench --light-scale` does: a rect light's sides or a
        /// sun's angular diameter; 0 makes a rect light a point light at its centre and a sun a
        /// hard one. A point light has nothing to scale.
        #[arg(long, default_value_t = 1.0)]
        light_scale: f32,
        /// Compare with a ground truth (`reference` or `reference-single-layer`): adds `error` to
        /// stats.json and writes reference.exr and error.png.
        #[arg(long, value_name = "REFERENCE")]
        compare_to: Option<String>,
        /// Light samples per axis of the reference (N×N rays for area lights).
        #[arg(long)]
        reference_samples: Option<u32>,
        #[command(flatten)]
        device: DeviceArgs,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// Every technique on one scene against the ray-cast reference: writes index.html, a
    /// contact sheet (each technique's image beside its error), errors.json/.csv and pareto.png.
    Compare {
        /// A scene file (.toml) or a procedural scene (e.g. `plane-boxes`).
        scene: String,
        /// Output directory (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Techniques, comma-separated; default: every technique except the references.
        #[arg(long, value_delimiter = ',')]
        techniques: Vec<String>,
        /// `KEY=VALUE` for every technique that has the knob, or `TECHNIQUE.KEY=VALUE` for one
        /// (repeatable).
        #[arg(long = "set", value_name = "[TECHNIQUE.]KEY=VALUE")]
        set: Vec<String>,
        /// The ground truth: `reference` or `reference-single-layer`.
        #[arg(long, default_value = "reference")]
        reference: String,
        /// Light samples per axis of the reference (N×N rays for area lights).
        #[arg(long)]
        reference_samples: Option<u32>,
        /// Timed frames per technique after one warm-up frame; times are medians.
        #[arg(long, default_value_t = 3)]
        frames: u32,
        #[command(flatten)]
        device: DeviceArgs,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// Run techniques × knob sweeps × scenes against the reference; write bench.json, bench.csv
    /// and Pareto charts.
    Bench {
        /// `techniques` (time and error of every technique), `kernels` (time and bandwidth of
        /// every compute primitive, and the SAT precision table) or `antialiasing` (analytic
        /// anti-aliasing against 8×8 supersampling of the same filter, both scored against
        /// 32×32 supersampling: the PVSSM paper's Fig. 11; one `--view-scale` for the base
        /// image, default technique `pvssm`) or `scaling` (each technique's time as triangles,
        /// view samples and the light grow, with fitted growth exponents and `scaling.png`) or
        /// `skipping` (every technique with its work skipping on and off: speed-up, output
        /// difference, what was skipped) or `selection` (the calibration table for
        /// `--technique auto`, then its check on ten held-out scenes, or on `--scenes` ×
        /// `--light-scale`) or `reuse` (the host CPU time of a technique's first frame, its next
        /// frame with the same renderer, and a rebuilt one: what keeping a `ShadowRenderer`
        /// saves) or `temporal` (shimmer: each technique's frame-to-frame change beyond the
        /// reference's as the light turns by `--light-step` and the camera slides by
        /// `--camera-step` a frame; techniques at their defaults but for `--set`).
        #[arg(long, default_value = "techniques")]
        suite: String,
        /// Scenes (files or procedural specs), comma-separated; default: every bundled scene.
        #[arg(long, value_delimiter = ',')]
        scenes: Vec<String>,
        /// Techniques, comma-separated; default: every technique except the references.
        #[arg(long, value_delimiter = ',')]
        techniques: Vec<String>,
        /// Sweep a knob: `key=v1,v2,...` (repeatable); replaces the default sweep of that knob in
        /// every technique that has it, or in one only as `technique.key=v1,v2,...`.
        #[arg(long = "set", value_name = "KEY=V1,V2")]
        set: Vec<String>,
        /// Small images, short sweeps, 8×8-sample references: a few minutes on lavapipe.
        #[arg(long)]
        quick: bool,
        /// `selection` suite: the error budget (penumbra MAE) the held-out picks must meet.
        #[arg(long, default_value_t = 0.05)]
        max_error: f64,
        /// Timed frames per run, after one warm-up frame (medians are reported).
        #[arg(long)]
        frames: Option<u32>,
        /// The ground truths to measure against, comma-separated: the first for the error
        /// columns and charts, each further one adds `penumbra_mae@NAME` and `rmse@NAME`
        /// (e.g. `reference,reference-single-layer`); `NAME:N` runs that one with N×N light
        /// samples instead of the bench's (32, quick 8).
        #[arg(long, default_value = "reference", value_delimiter = ',')]
        reference: Vec<String>,
        /// Light-size factors, comma-separated: each scene also runs with its light scaled
        /// (rect edges, angular diameter; point lights are run once; 0 turns a rect light into a
        /// point light at its centre, and a directional one into a hard sun).
        #[arg(long, default_value = "1", value_delimiter = ',')]
        light_scale: Vec<f32>,
        /// `temporal` suite: milliradians the light turns about the camera's target a frame.
        #[arg(long, default_value_t = 0.25)]
        light_step: f32,
        /// `temporal` suite: pixels the camera slides sideways a frame (its target with it).
        #[arg(long, default_value_t = 0.0)]
        camera_step: f32,
        /// `temporal` suite: positions (frames) of the light and the camera along their paths.
        #[arg(long, default_value_t = 8)]
        positions: u32,
        /// Camera-distance factors, comma-separated: each scene also runs with its camera moved
        /// along its view ray to this multiple of its distance from the target (e.g. `1,0.5,0.25`
        /// to see how many pages a virtual map renders as the camera closes in).
        #[arg(long, default_value = "1", value_delimiter = ',')]
        camera_scale: Vec<f32>,
        /// Image-size factors, comma-separated: each scene also runs with its camera's width and
        /// height scaled (e.g. `0.5,1,2` for a technique's time against the number of view
        /// samples); applied after `--quick`'s halving.
        #[arg(long, default_value = "1", value_delimiter = ',')]
        view_scale: Vec<f32>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        device: DeviceArgs,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// Run the stress suite: adversarial cases × techniques, each row checked for NaN, infinite
    /// and out-of-range visibility and held to a bound stated per case and technique; write
    /// stress.json (exits non-zero if a row fails).
    Stress {
        /// The CI subset of cases at 128×96 with 4×4-sample references (else every case at
        /// 256×192, 8×8).
        #[arg(long)]
        quick: bool,
        /// Cases, comma-separated (default: all, or the quick ones); the baseline always runs.
        #[arg(long, value_delimiter = ',')]
        cases: Vec<String>,
        /// Techniques, comma-separated; default: every technique except the references.
        #[arg(long, value_delimiter = ',')]
        techniques: Vec<String>,
        /// Knob values, `key=value`, repeatable: set on every technique that has the knob (a
        /// case's own knobs win).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        device: DeviceArgs,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// List Vulkan devices and the features that matter to penumbra.
    Devices {
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// List techniques with their knobs, defaults and ranges.
    Techniques {
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// List procedural scenes.
    Scenes,
}
