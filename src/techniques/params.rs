//! Technique knobs: declared once per technique with default and range, resolved from
//! `key=value` strings with clear errors, listed by `penumbra techniques`.

use std::collections::BTreeMap;

use crate::error::{Error, Result};
use crate::scene::SceneDefaults;

/// Where a knob's default comes from.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum KnobDefault {
    /// A fixed value.
    Value(f64),
    /// The scene file's `[defaults]` entry of this name.
    Scene(&'static str),
}

/// One knob of a technique.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Knob {
    /// Stable snake_case name, as given to `--set`.
    pub name: &'static str,
    /// One line: what it does and its unit.
    pub summary: &'static str,
    /// The default.
    pub default: KnobDefault,
    /// Smallest accepted value.
    pub min: f64,
    /// Largest accepted value.
    pub max: f64,
    /// Whether only integers are accepted.
    pub integer: bool,
    /// Names accepted for the integer values 0, 1, … (e.g. `fit = scene | view`); empty for a
    /// plain number. A knob with names also accepts the numbers.
    pub names: &'static [&'static str],
}

impl Knob {
    /// An integer knob with a fixed default.
    pub const fn int(
        name: &'static str,
        summary: &'static str,
        default: f64,
        min: f64,
        max: f64,
    ) -> Knob {
        Knob {
            name,
            summary,
            default: KnobDefault::Value(default),
            min,
            max,
            integer: true,
            names: &[],
        }
    }

    /// The same knob taking any real value in its range.
    pub const fn real(self) -> Knob {
        Knob {
            integer: false,
            ..self
        }
    }

    /// The same knob with names for its integer values 0, 1, …
    pub const fn named(self, names: &'static [&'static str]) -> Knob {
        Knob { names, ..self }
    }
}

/// The knobs every shadow-map technique has.
pub const SHADOW_MAP_KNOBS: [Knob; 4] = [
    Knob {
        name: "map_size",
        summary: "shadow-map width and height in texels",
        default: KnobDefault::Scene("shadow_map_size"),
        min: 16.0,
        max: 16384.0,
        integer: true,
        names: &[],
    },
    Knob {
        name: "bias_constant",
        summary: "rasterizer constant depth bias (units of the D32 depth ulp)",
        default: KnobDefault::Scene("bias_constant"),
        min: -1.0e6,
        max: 1.0e6,
        integer: false,
        names: &[],
    },
    Knob {
        name: "bias_slope",
        summary: "rasterizer slope-scaled depth bias",
        default: KnobDefault::Scene("bias_slope"),
        min: -100.0,
        max: 100.0,
        integer: false,
        names: &[],
    },
    Knob {
        name: "bias_clamp",
        summary: "largest depth bias (0: unclamped; needs depthBiasClamp)",
        default: KnobDefault::Value(0.0),
        min: 0.0,
        max: 1.0,
        integer: false,
        names: &[],
    },
];

/// `light_clip`: the part of the light behind the receiver's tangent plane is hidden by the
/// receiver itself (what the ray-cast reference assumes).
pub const LIGHT_CLIP: Knob = Knob {
    name: "light_clip",
    summary:
        "1: the light behind the receiver's tangent plane is blocked (as the reference); 0: off",
    default: KnobDefault::Value(1.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &[],
};

/// `normal_offset`: the lookup position pushed along the receiver's normal (book §2.2.3).
pub const NORMAL_OFFSET: Knob = Knob {
    name: "normal_offset",
    summary: "normal-offset bias: the lookup moves along the receiver's normal by this many \
              shadow-map texels (world size at the receiver)",
    default: KnobDefault::Value(0.0),
    min: 0.0,
    max: 16.0,
    integer: false,
    names: &[],
};

/// `fit`: what the light view is fitted to.
pub const FIT: Knob = Knob {
    name: "fit",
    summary: "light view fitted to the scene's bounding box (scene) or to the view samples and \
              the casters between them and the light (view)",
    default: KnobDefault::Value(1.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &["scene", "view"],
};

/// `horizon_skip`: whether samples whose tangent plane hides the whole light skip the technique.
pub const HORIZON_SKIP: Knob = Knob {
    name: "horizon_skip",
    summary: "1: samples whose tangent plane hides the whole light are umbra without the \
              technique's work (same output); 0: evaluated, then overwritten (to measure the skip)",
    default: KnobDefault::Value(1.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &[],
};

/// `hard_path`: a soft technique whose light cannot cast a penumbra half a texel wide on its map
/// renders the hard test instead (the engine decides from the light's footprint at the nearest
/// possible blocker and the farthest receiver; counted as `hard_path`). Off by default: under a
/// point light the soft techniques' minimum kernel is a one-texel box filter, which the hard
/// test is not, and the measured tables were made with it.
pub const HARD_PATH: Knob = Knob {
    name: "hard_path",
    summary: "1: under a light too small to cast a penumbra half a texel wide (a point light), \
              render the hard test instead (counted as hard_path); 0: always the soft technique",
    default: KnobDefault::Value(0.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &[],
};

/// `caster_skip`: when the engine proves that no triangle can shadow any view sample, the
/// technique is replaced by the lit answer (no map at all; see [`crate::passes::caster_cull`]).
pub const CASTER_SKIP: Knob = Knob {
    name: "caster_skip",
    summary: "1: when no triangle can shadow any view sample, write the lit answer without a \
              map (counted as caster_skip; exact); 0: always the technique (to measure the skip)",
    default: KnobDefault::Value(1.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &[],
};

/// The knobs the engine adds to every shadow-map technique: it prepares the receivers (light
/// clipping, normal offset, horizon umbra) and the light view around the technique (see
/// [`crate::passes::receivers`]).
pub const RECEIVER_KNOBS: [Knob; 4] = [LIGHT_CLIP, NORMAL_OFFSET, HORIZON_SKIP, FIT];

/// Resolved knob values of one technique instance.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct Params {
    /// The technique the knobs were resolved for (named in errors).
    #[serde(skip)]
    technique: String,
    values: BTreeMap<String, f64>,
}

fn scene_default(defaults: &SceneDefaults, key: &str) -> Option<f64> {
    match key {
        "shadow_map_size" => Some(defaults.shadow_map_size as f64),
        "bias_constant" => Some(defaults.bias_constant as f64),
        "bias_slope" => Some(defaults.bias_slope as f64),
        _ => None,
    }
}

impl Params {
    /// Resolves `overrides` (`key` → textual value) against `knobs`, filling the rest with
    /// defaults. Unknown keys, unparsable or out-of-range values are errors naming the knob.
    pub fn resolve(
        technique: &str,
        knobs: &[Knob],
        overrides: &BTreeMap<String, String>,
        defaults: &SceneDefaults,
    ) -> Result<Params> {
        let err = |message: String| Error::Parameter {
            technique: technique.to_string(),
            message,
        };
        for key in overrides.keys() {
            if !knobs.iter().any(|k| k.name == key) {
                let names: Vec<_> = knobs.iter().map(|k| k.name).collect();
                return Err(err(format!(
                    "unknown knob '{key}'; knobs: {}",
                    if names.is_empty() {
                        "(none)".to_string()
                    } else {
                        names.join(", ")
                    }
                )));
            }
        }
        let mut values = BTreeMap::new();
        for k in knobs {
            let value = match overrides.get(k.name) {
                Some(text) => match k.names.iter().position(|n| *n == text.trim()) {
                    Some(index) => index as f64,
                    None => text.trim().parse::<f64>().map_err(|_| {
                        err(if k.names.is_empty() {
                            format!("knob '{}' = '{text}' is not a number", k.name)
                        } else {
                            format!(
                                "knob '{}' = '{text}' is not one of {} (or their index)",
                                k.name,
                                k.names.join(", ")
                            )
                        })
                    })?,
                },
                None => match k.default {
                    KnobDefault::Value(v) => v,
                    KnobDefault::Scene(key) => scene_default(defaults, key)
                        .ok_or_else(|| err(format!("no scene default '{key}'")))?,
                },
            };
            if !value.is_finite() || value < k.min || value > k.max {
                return Err(err(format!(
                    "knob '{}' = {value} is outside [{}, {}]",
                    k.name, k.min, k.max
                )));
            }
            if k.integer && value.fract() != 0.0 {
                return Err(err(format!(
                    "knob '{}' = {value} must be an integer",
                    k.name
                )));
            }
            values.insert(k.name.to_string(), value);
        }
        Ok(Params {
            technique: technique.to_string(),
            values,
        })
    }

    /// A knob's value. A name the technique does not declare is an error, not a silent 0: a
    /// technique reading a knob it forgot to declare would otherwise run with a wrong constant.
    pub fn get(&self, name: &str) -> Result<f64> {
        self.values
            .get(name)
            .copied()
            .ok_or_else(|| Error::Parameter {
                technique: self.technique.clone(),
                message: format!("knob '{name}' is read but not declared by the technique"),
            })
    }

    /// A knob's value as `f32`.
    pub fn f32(&self, name: &str) -> Result<f32> {
        Ok(self.get(name)? as f32)
    }

    /// An integer knob's value (declared integer knobs are whole and within `[min, max]`).
    pub fn u32(&self, name: &str) -> Result<u32> {
        Ok(self.get(name)? as u32)
    }

    /// Every resolved value.
    pub fn values(&self) -> &BTreeMap<String, f64> {
        &self.values
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A declared knob reads its value; an undeclared one is an error naming the technique and
    /// the knob, never a silent 0.
    #[test]
    fn undeclared_knob_is_an_error() {
        let params = Params::resolve(
            "pcf",
            &SHADOW_MAP_KNOBS,
            &BTreeMap::from([("map_size".to_string(), "512".to_string())]),
            &SceneDefaults::default(),
        )
        .expect("declared knobs");
        assert_eq!(params.u32("map_size").expect("declared"), 512);
        let named = Params::resolve(
            "pcf",
            &[FIT],
            &BTreeMap::from([("fit".to_string(), "scene".to_string())]),
            &SceneDefaults::default(),
        )
        .expect("a named value");
        assert_eq!(named.u32("fit").expect("declared"), 0);
        let bad = BTreeMap::from([("fit".to_string(), "camera".to_string())]);
        let err = Params::resolve("pcf", &[FIT], &bad, &SceneDefaults::default())
            .expect_err("not a name")
            .to_string();
        assert!(err.contains("scene, view"), "{err}");
        assert_eq!(params.f32("bias_clamp").expect("declared"), 0.0);
        let err = params.get("kernel").expect_err("not declared").to_string();
        assert!(err.contains("pcf") && err.contains("kernel"), "{err}");
    }
}
