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
    },
    Knob {
        name: "bias_constant",
        summary: "rasterizer constant depth bias (units of the D32 depth ulp)",
        default: KnobDefault::Scene("bias_constant"),
        min: -1.0e6,
        max: 1.0e6,
        integer: false,
    },
    Knob {
        name: "bias_slope",
        summary: "rasterizer slope-scaled depth bias",
        default: KnobDefault::Scene("bias_slope"),
        min: -100.0,
        max: 100.0,
        integer: false,
    },
    Knob {
        name: "bias_clamp",
        summary: "largest depth bias (0: unclamped; needs depthBiasClamp)",
        default: KnobDefault::Value(0.0),
        min: 0.0,
        max: 1.0,
        integer: false,
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
};

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
                Some(text) => text
                    .trim()
                    .parse::<f64>()
                    .map_err(|_| err(format!("knob '{}' = '{text}' is not a number", k.name)))?,
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
        assert_eq!(params.f32("bias_clamp").expect("declared"), 0.0);
        let err = params.get("kernel").expect_err("not declared").to_string();
        assert!(err.contains("pcf") && err.contains("kernel"), "{err}");
    }
}
