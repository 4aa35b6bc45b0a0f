//! What a bench run runs: each technique's default knob sweep (quick or full) with the user's
//! `--set` lists in place of its own, the scene variants (light, camera and image scales), the
//! ground truths, and the scenes a suite opens.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::Context as _;
use penumbra::scene::Scene;

use crate::bench::BenchArgs;

/// The default sweep of a technique's knobs: (quick, full).
pub(crate) fn default_sweep(technique: &str, quick: bool) -> Vec<(&'static str, Vec<f64>)> {
    match (technique, quick) {
        ("hard", true) => vec![("map_size", vec![512.0, 1024.0])],
        ("hard", false) => vec![("map_size", vec![512.0, 1024.0, 2048.0, 4096.0, 8192.0])],
        // Warping: the optimal parameter and a weaker warp.
        ("lispsm", true) => vec![("map_size", vec![1024.0])],
        ("lispsm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("n_scale", vec![1.0, 4.0]),
        ],
        // Cascades: practical splits against SDSM (partition 0 = pssm, 1 = sdsm, 2 = uniform,
        // 3 = log) at four maps of 512² (quick) or 1024² (= one 2048² map's memory).
        ("cascades", true) => vec![("map_size", vec![512.0]), ("partition", vec![0.0, 1.0])],
        ("cascades", false) => vec![
            ("map_size", vec![1024.0]),
            ("partition", vec![0.0, 1.0, 2.0, 3.0]),
        ],
        ("pcf", true) => vec![("map_size", vec![1024.0]), ("kernel", vec![1.0, 3.0, 5.0])],
        ("pcf", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("kernel", vec![1.0, 3.0, 5.0, 9.0]),
        ],
        // Wide kernels with one receiver depth are mostly acne (misclassified ~0.8 on
        // plane-boxes), so the quick sweep measures the filters with receiver-plane bias on.
        ("pcf-poisson", true) => vec![
            ("map_size", vec![1024.0]),
            ("taps", vec![8.0, 16.0, 32.0]),
            ("receiver_plane_bias", vec![1.0]),
        ],
        ("pcf-poisson", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("taps", vec![8.0, 16.0, 32.0]),
            ("receiver_plane_bias", vec![1.0]),
        ],
        ("pcf-coverage", true) => vec![
            ("map_size", vec![1024.0]),
            ("kernel", vec![1.5, 3.0, 5.0]),
            ("receiver_plane_bias", vec![1.0]),
        ],
        ("pcf-coverage", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("kernel", vec![1.0, 2.5, 5.0, 9.0]),
            ("receiver_plane_bias", vec![1.0]),
        ],
        ("average-maps", true) => vec![("map_size", vec![512.0]), ("samples", vec![16.0])],
        ("average-maps", false) => vec![
            ("map_size", vec![1024.0]),
            ("samples", vec![16.0, 64.0, 256.0]),
        ],
        // Filtered shadow maps: blur radius, and each technique's own axis (exponents, M).
        ("vsm", true) => vec![
            ("map_size", vec![1024.0]),
            ("filter_radius", vec![1.0, 2.0]),
        ],
        ("vsm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("filter_radius", vec![1.0, 2.0, 4.0]),
        ],
        ("esm", true) => vec![("map_size", vec![1024.0]), ("exponent", vec![40.0, 80.0])],
        ("esm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("exponent", vec![40.0, 80.0, 200.0]),
        ],
        ("evsm", true) => vec![("map_size", vec![1024.0]), ("components", vec![2.0, 4.0])],
        ("evsm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("components", vec![2.0, 4.0]),
        ],
        ("msm", true) => vec![
            ("map_size", vec![1024.0]),
            ("filter_radius", vec![1.0, 2.0]),
        ],
        ("msm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("filter_radius", vec![1.0, 2.0, 4.0]),
        ],
        ("csm", true) => vec![("map_size", vec![1024.0]), ("terms", vec![4.0, 8.0, 16.0])],
        ("csm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("terms", vec![4.0, 8.0, 16.0]),
        ],
        // Summed-area VSM: the cost should not grow with the kernel.
        ("savsm", true) => vec![("map_size", vec![1024.0]), ("kernel", vec![3.0, 9.0])],
        ("savsm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("kernel", vec![3.0, 9.0, 17.0, 33.0]),
        ],
        // PCSS: exhaustive and 8x8-grid blocker search, skipping off and by pyramid (the skip
        // table pairs them; the N-buffer is compared in the README's own run); a one-texel
        // normal offset lifts receivers clear of their own surface.
        ("pcss", true) => vec![
            ("map_size", vec![1024.0]),
            ("search_taps", vec![8.0]),
            ("skip", vec![0.0, 2.0]),
            ("normal_offset", vec![1.0]),
        ],
        ("pcss", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("search_taps", vec![0.0, 8.0]),
            ("skip", vec![0.0, 2.0]),
            ("normal_offset", vec![1.0]),
        ],
        // Convolution soft shadows: M, the cost driver (6M + 1 table builds per frame).
        ("cssm", true) => vec![("map_size", vec![1024.0]), ("terms", vec![4.0, 8.0, 16.0])],
        ("cssm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("terms", vec![4.0, 8.0, 16.0]),
            ("resident", vec![0.0, 1.0]),
        ],
        // Variance soft shadow mapping: subdivision against leaks (1 = plain VSM's lit), and
        // which regions split at which depths (the paper's rule: leaks at one depth).
        ("vssm", true) => vec![("map_size", vec![1024.0]), ("subdivision", vec![1.0, 4.0])],
        ("vssm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("subdivision", vec![1.0, 4.0]),
            ("split_regions", vec![0.0, 1.0]),
            ("receiver_plane_bias", vec![0.0, 1.0]),
        ],
        // Exponential soft shadow mapping: the exponent trades leaks for a sharper step; the
        // filter tested per block at the receiver plane's depth, or once at one depth (the
        // paper's).
        ("essm", true) => vec![("map_size", vec![1024.0]), ("exponent", vec![40.0, 80.0])],
        ("essm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("exponent", vec![40.0, 80.0, 200.0]),
            ("receiver_plane_bias", vec![0.0, 1.0]),
        ],
        // Resolution-matched virtual maps, with the default pool (1024 pages of 64², one 2048²
        // map): the virtual size against `hard`'s map size (the finest level it may reach), and
        // the shadow-edge refinement off and on.
        ("rmsm", true) => vec![("virtual_size", vec![2048.0, 32768.0])],
        ("rmsm", false) => vec![
            (
                "virtual_size",
                vec![1024.0, 2048.0, 4096.0, 8192.0, 32768.0],
            ),
            ("refine", vec![0.0, 4.0]),
        ],
        // PVSSM: the perceptual metric's quality dial and the analytic anti-aliasing.
        ("pvssm", true) => vec![("rho_scale", vec![1.0])],
        ("pvssm", false) => vec![
            ("rho_scale", vec![0.5, 1.0, 2.0]),
            ("antialias", vec![0.0, 1.0]),
        ],
        // Irregular z-buffer: the grid (cells per side over the view samples' bounds) and, soft,
        // the light samples per view sample.
        ("izb", true) => vec![("grid", vec![128.0])],
        ("izb", false) => vec![("grid", vec![64.0, 128.0, 512.0, 2048.0])],
        ("izb-soft", true) => vec![("samples", vec![32.0])],
        ("izb-soft", false) => vec![("samples", vec![32.0, 128.0, 512.0])],
        // Soft shadow maps: the occluder map's size (the paper's 128²–256² and one finer) and
        // the two-sided variant.
        ("atty", true) => vec![("map_size", vec![256.0])],
        ("atty", false) => vec![
            ("map_size", vec![128.0, 256.0, 512.0]),
            ("sides", vec![1.0, 2.0]),
        ],
        // Occlusion bitmasks: the map, the light samples, and OR-ed masks against the additive
        // sum of areas they replace.
        ("bitmask", true) => vec![("map_size", vec![512.0]), ("samples", vec![64.0])],
        ("bitmask", false) => vec![
            ("map_size", vec![512.0, 1024.0]),
            ("samples", vec![64.0, 256.0, 1024.0]),
            ("combine", vec![0.0, 1.0]),
        ],
        _ => Vec::new(),
    }
}

/// `--set key=v1,v2,...`: each knob's values, which replace that knob's sweep in every technique
/// that has it.
pub(crate) fn user_sweep(sets: &[String]) -> anyhow::Result<BTreeMap<String, Vec<String>>> {
    let mut sweep = BTreeMap::new();
    for s in sets {
        let (k, v) = s
            .split_once('=')
            .with_context(|| format!("--set '{s}': expected KEY=V1,V2,..."))?;
        sweep.insert(
            k.trim().into(),
            v.split(',').map(|x| x.trim().to_string()).collect(),
        );
    }
    Ok(sweep)
}

/// Every (light scale, camera scale, view scale) a scene is run with, each factor checked.
pub(crate) fn variants(args: &BenchArgs) -> anyhow::Result<Vec<(f32, f32, f32)>> {
    if let Some(bad) = args
        .light_scales
        .iter()
        .find(|s| !(s.is_finite() && **s >= 0.0 && **s <= 100.0))
    {
        anyhow::bail!("--light-scale {bad}: expected a factor in [0, 100] (0: a rect light's centre as a point light, a hard sun)");
    }
    if let Some(bad) = args
        .camera_scales
        .iter()
        .find(|s| !(s.is_finite() && **s > 0.0 && **s <= 100.0))
    {
        anyhow::bail!("--camera-scale {bad}: expected a factor in (0, 100]");
    }
    if let Some(bad) = args
        .view_scales
        .iter()
        .find(|s| !(s.is_finite() && **s > 0.0 && **s <= 8.0))
    {
        anyhow::bail!("--view-scale {bad}: expected a factor in (0, 8]");
    }
    Ok(args
        .light_scales
        .iter()
        .flat_map(|&l| {
            args.camera_scales
                .iter()
                .flat_map(move |&c| args.view_scales.iter().map(move |&v| (l, c, v)))
        })
        .collect())
}

/// Every (technique, knob overrides) a scene variant runs: each technique's default sweep (the
/// quick one with `Some(true)`; none, the technique at its defaults, with `None`), a knob of
/// `user_sweep` in place of its own where the technique has that knob. A knob scoped
/// `TECHNIQUE.KEY` goes to that technique only, over an unscoped one of the same name (so
/// `--set samples=64 --set reference.samples=32` sweeps `average-maps`'s 64 maps and times the
/// reference at its own rays); its technique must be one of those run, and have the knob.
pub(crate) fn runs(
    techniques: &[String],
    user_sweep: &BTreeMap<String, Vec<String>>,
    quick: Option<bool>,
) -> anyhow::Result<Vec<(String, BTreeMap<String, String>)>> {
    for key in user_sweep.keys() {
        if let Some((technique, knob)) = key.split_once('.') {
            anyhow::ensure!(
                techniques.iter().any(|t| t == technique),
                "--set {key}: '{technique}' is not one of the techniques run"
            );
            let info = penumbra::techniques::find(technique)?;
            anyhow::ensure!(
                info.all_knobs().iter().any(|kn| kn.name == knob),
                "--set {key}: '{technique}' has no knob '{knob}'"
            );
        }
    }
    let mut plan = Vec::new();
    for t in techniques {
        let info = penumbra::techniques::find(t)?;
        let defaults = quick.map_or_else(Vec::new, |quick| default_sweep(t, quick));
        let mut sweep: Vec<(String, Vec<String>)> = defaults
            .into_iter()
            .map(|(k, vs)| (k.to_string(), vs.iter().map(|v| v.to_string()).collect()))
            .collect();
        let knobs = info.all_knobs();
        for (k, vs) in user_sweep {
            let knob = match k.split_once('.') {
                Some((technique, knob)) if technique == t => knob,
                // An unscoped knob, unless this technique has it scoped too.
                None if !user_sweep.contains_key(&format!("{t}.{k}")) => k.as_str(),
                _ => continue,
            };
            if knobs.iter().any(|kn| kn.name == knob) {
                sweep.retain(|(sk, _)| sk != knob);
                sweep.push((knob.to_string(), vs.clone()));
            }
        }
        for combo in combinations(&sweep) {
            plan.push((t.clone(), combo));
        }
    }
    Ok(plan)
}

/// The ground truths, `NAME` or `NAME:SAMPLES` (N×N light samples, 1–256; `default_samples`
/// without), each a technique: (name, samples). The first is the primary one.
pub(crate) fn reference_specs(
    references: &[String],
    default_samples: &str,
) -> anyhow::Result<Vec<(String, String)>> {
    let mut specs = Vec::new();
    for spec in references {
        let (name, samples) = match spec.split_once(':') {
            Some((n, s)) => {
                let n_samples: u32 = s
                    .parse()
                    .ok()
                    .filter(|v| (1..=256).contains(v))
                    .with_context(|| format!("--reference {spec}: expected NAME:SAMPLES, 1–256"))?;
                (n.to_string(), n_samples.to_string())
            }
            None => (spec.clone(), default_samples.to_string()),
        };
        penumbra::techniques::find(&name)?;
        specs.push((name, samples));
    }
    anyhow::ensure!(!specs.is_empty(), "at least one --reference is needed");
    Ok(specs)
}

/// The scene `spec` as the variant (light, camera, view scale) runs it, named after the
/// factors that are not 1 (half size with `quick`), or `None` where the light has no size to
/// scale (a point light: the scale-1 runs cover it).
pub(crate) fn scene_variant(
    spec: &str,
    quick: bool,
    (light_scale, camera_scale, view_scale): (f32, f32, f32),
) -> anyhow::Result<Option<Scene>> {
    let mut scene = Scene::open(spec)?;
    if quick {
        scene.camera.width = (scene.camera.width / 2).max(16);
        scene.camera.height = (scene.camera.height / 2).max(16);
    }
    if light_scale != 1.0 {
        if !scale_light(&mut scene.light, light_scale) {
            return Ok(None);
        }
        scene.name = format!("{}-light{light_scale}", scene.name);
    }
    if view_scale != 1.0 {
        let camera = &mut scene.camera;
        camera.width = ((camera.width as f32 * view_scale).round() as u32).max(16);
        camera.height = ((camera.height as f32 * view_scale).round() as u32).max(16);
        scene.name = format!("{}-view{view_scale}", scene.name);
    }
    if camera_scale != 1.0 {
        let camera = &mut scene.camera;
        camera.position = camera.target + (camera.position - camera.target) * camera_scale;
        scene.name = format!("{}-camera{camera_scale}", scene.name);
    }
    Ok(Some(scene))
}

/// Opens the scenes a suite runs on: scene files or procedural specs, or `stress:NAME` for a
/// stress case's scene (at `size`, its builder's argument); `size` also resizes the others'
/// cameras when given.
pub fn suite_scenes(
    specs: &[String],
    size: Option<(u32, u32)>,
) -> anyhow::Result<Vec<penumbra::scene::Scene>> {
    let (w, h) = size.unwrap_or((512, 384));
    specs
        .iter()
        .map(|spec| {
            if let Some(name) = spec.strip_prefix("stress:") {
                let Some(case) = penumbra::stress::cases::cases()
                    .into_iter()
                    .find(|c| c.name == name)
                else {
                    anyhow::bail!("--scenes {spec}: no stress case '{name}' (see penumbra stress)");
                };
                let mut scene = (case.scene)(w, h)?;
                scene.name = name.to_string();
                return Ok(scene);
            }
            let mut scene = penumbra::scene::Scene::open(spec)?;
            if size.is_some() {
                scene.camera.width = w;
                scene.camera.height = h;
            }
            Ok(scene)
        })
        .collect()
}

pub fn bundled_scenes() -> anyhow::Result<Vec<String>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut scenes: Vec<String> = std::fs::read_dir(&dir)
        .with_context(|| format!("listing {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .map(|p| p.display().to_string())
        .collect();
    scenes.sort();
    Ok(scenes)
}

/// Every combination of the sweep's values, as knob overrides.
pub(crate) fn combinations(sweep: &[(String, Vec<String>)]) -> Vec<BTreeMap<String, String>> {
    let mut out = vec![BTreeMap::new()];
    for (key, values) in sweep {
        out = out
            .into_iter()
            .flat_map(|base| {
                values.iter().map(move |v| {
                    let mut m = base.clone();
                    m.insert(key.clone(), v.clone());
                    m
                })
            })
            .collect();
    }
    out
}

/// A run's knob overrides as `key=value ...`, or `defaults`.
pub(crate) fn label(overrides: &BTreeMap<String, String>) -> String {
    if overrides.is_empty() {
        return "defaults".into();
    }
    overrides
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Scales a light's size by `s` (rect edges, angular diameter); false for a point light. A
/// rect light scaled by 0 becomes a point light at its centre, a sun a hard sun (angular
/// diameter 0): the same scene lit hard, to compare a technique's soft and hard costs.
pub(crate) fn scale_light(light: &mut penumbra::scene::Light, s: f32) -> bool {
    use penumbra::scene::Light;
    match light {
        Light::Point { .. } => false,
        Light::Rect { position, .. } if s == 0.0 => {
            *light = Light::Point {
                position: *position,
            };
            true
        }
        Light::Rect { u, v, .. } => {
            *u *= s;
            *v *= s;
            true
        }
        Light::Directional {
            angular_diameter_deg,
            ..
        } => {
            *angular_diameter_deg *= s;
            true
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{runs, scale_light, user_sweep};
    use glam::Vec3;
    use penumbra::scene::Light;

    #[test]
    fn light_scale_zero_lights_the_scene_hard() {
        let mut rect = Light::Rect {
            position: Vec3::Y,
            u: Vec3::X,
            v: Vec3::Z,
        };
        assert!(scale_light(&mut rect, 0.0));
        assert!(matches!(rect, Light::Point { position } if position == Vec3::Y));
        let mut sun = Light::Directional {
            direction: -Vec3::Y,
            angular_diameter_deg: 0.5,
        };
        assert!(scale_light(&mut sun, 4.0));
        assert!(
            matches!(sun, Light::Directional { angular_diameter_deg, .. } if angular_diameter_deg == 2.0)
        );
        assert!(scale_light(&mut sun, 0.0));
        assert!(
            matches!(sun, Light::Directional { angular_diameter_deg, .. } if angular_diameter_deg == 0.0)
        );
        let mut point = Light::Point {
            position: Vec3::ZERO,
        };
        assert!(!scale_light(&mut point, 2.0));
    }

    #[test]
    fn a_scoped_knob_goes_to_its_technique_only() {
        let techniques = ["average-maps".to_string(), "reference".to_string()];
        let sets = [
            "samples=64".to_string(),
            "reference.samples=8,16".to_string(),
        ];
        let plan = runs(&techniques, &user_sweep(&sets).unwrap(), Some(false)).unwrap();
        let samples: Vec<(&str, &str)> = plan
            .iter()
            .map(|(t, knobs)| (t.as_str(), knobs["samples"].as_str()))
            .collect();
        assert_eq!(
            samples,
            [
                ("average-maps", "64"),
                ("reference", "8"),
                ("reference", "16")
            ]
        );
        // A scope names a technique that is run, and a knob it has.
        for bad in ["pcss.samples=4", "reference.map_size=512"] {
            let err = runs(
                &techniques,
                &user_sweep(&[bad.to_string()]).unwrap(),
                Some(false),
            )
            .unwrap_err()
            .to_string();
            assert!(err.contains(bad.split('=').next().unwrap()), "{err}");
        }
    }
}
