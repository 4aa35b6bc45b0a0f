//! `pvssm`'s knobs as the shaders' option bits: the push block's `options` word, whose layout
//! is `glsl/pvssm/pvssm.glsl`'s `OPT_*` defines (a test checks the two against each other).

use super::super::Params;
use crate::error::{Error, Result};

/// `antialias = 1`: the pixel footprint in the kernel.
const ANTIALIAS: u32 = 1;
/// `rho = static`: the static-occluder cubic.
const RHO_STATIC: u32 = 2;
/// `ancestors = 1`: every page's coarser ancestors requested too.
const ANCESTORS: u32 = 4;
/// `skip = 1`: the coarse early-out before the blocker search.
const COARSE_SKIP: u32 = 8;
/// `blocker_depth = silhouette`.
const SILHOUETTE: u32 = 16;
/// `kernel_proof >= 1`: samples whose kernel's reach holds no blocker decided lit.
const KERNEL_PROOF: u32 = 32;
/// The visibility was cleared to 1 by the host: a sample decided lit stores nothing.
const LIT_CLEARED: u32 = 64;
/// `blocker_distance = centre`.
const CENTRE_DISTANCE: u32 = 128;
/// Bits 8..15: the blocker search's cells per side (`search_cells`).
const CELLS_SHIFT: u32 = 8;
/// Bit 16 up: `refine_search`.
const REFINE_SHIFT: u32 = 16;
/// Bits 20..23: `fixed_level` + 1, 0 for the predicted level.
const FIXED_SHIFT: u32 = 20;
/// `lit_flag = conservative`.
const LIT_CONSERVATIVE: u32 = 1 << 24;
/// Bits 25..28: log2(`max_anisotropy`) + 1, 0 for no cap.
const ANISO_SHIFT: u32 = 25;
/// `kernel_proof = 2`: that proof tried before the refined search.
const KERNEL_PROOF_FIRST: u32 = 1 << 29;

/// The `options` word for these knobs; `lit_cleared` where the visibility image is cleared to 1
/// by a transfer before the shape pass (the engine's is; a caller's may lack the usage).
pub(super) fn option_bits(params: &Params, lit_cleared: bool) -> Result<u32> {
    let flag = |on: bool, bit: u32| if on { bit } else { 0 };
    let kernel_proof = params.u32("kernel_proof")?;
    let max_anisotropy = params.u32("max_anisotropy")?;
    let aniso = match max_anisotropy {
        0 => 0,
        m if m.is_power_of_two() => m.trailing_zeros() + 1,
        m => {
            return Err(Error::Parameter {
                technique: "pvssm".into(),
                message: format!("max_anisotropy {m} must be 0 (no cap) or a power of two"),
            })
        }
    };
    // -1 (predicted) is stored as 0, level k as k + 1.
    let fixed = (params.f32("fixed_level")? + 1.0) as u32;
    Ok(flag(params.u32("antialias")? == 1, ANTIALIAS)
        | flag(params.u32("rho")? == 1, RHO_STATIC)
        | flag(params.u32("ancestors")? == 1, ANCESTORS)
        | flag(params.u32("skip")? == 1, COARSE_SKIP)
        | flag(params.u32("blocker_depth")? == 1, SILHOUETTE)
        | flag(kernel_proof >= 1, KERNEL_PROOF)
        | flag(kernel_proof == 2, KERNEL_PROOF_FIRST)
        | flag(lit_cleared, LIT_CLEARED)
        | flag(params.u32("blocker_distance")? == 1, CENTRE_DISTANCE)
        | flag(params.u32("lit_flag")? == 1, LIT_CONSERVATIVE)
        | params.u32("search_cells")? << CELLS_SHIFT
        | params.u32("refine_search")? << REFINE_SHIFT
        | fixed << FIXED_SHIFT
        | aniso << ANISO_SHIFT)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each constant is the value of the shader's define of the same name.
    #[test]
    fn the_bits_are_the_shaders() {
        let source = include_str!("../../../glsl/pvssm/pvssm.glsl");
        let value = |name: &str| -> u32 {
            let line = source
                .lines()
                .find(|l| l.starts_with(&format!("#define OPT_{name} ")))
                .unwrap_or_else(|| panic!("OPT_{name} not defined"));
            let v = line.split_whitespace().skip(2).collect::<String>();
            let v = v
                .trim_start_matches('(')
                .trim_end_matches(')')
                .replace('u', "");
            match v.split_once("<<") {
                Some((a, b)) => a.parse::<u32>().expect("a") << b.parse::<u32>().expect("b"),
                None => v.parse().expect("a number"),
            }
        };
        for (name, bits) in [
            ("ANTIALIAS", ANTIALIAS),
            ("RHO_STATIC", RHO_STATIC),
            ("ANCESTORS", ANCESTORS),
            ("COARSE_SKIP", COARSE_SKIP),
            ("SILHOUETTE", SILHOUETTE),
            ("KERNEL_PROOF", KERNEL_PROOF),
            ("LIT_CLEARED", LIT_CLEARED),
            ("CENTRE_DISTANCE", CENTRE_DISTANCE),
            ("CELLS_SHIFT", CELLS_SHIFT),
            ("REFINE_SHIFT", REFINE_SHIFT),
            ("FIXED_SHIFT", FIXED_SHIFT),
            ("LIT_CONSERVATIVE", LIT_CONSERVATIVE),
            ("ANISO_SHIFT", ANISO_SHIFT),
            ("KERNEL_PROOF_FIRST", KERNEL_PROOF_FIRST),
        ] {
            assert_eq!(value(name), bits, "OPT_{name}");
        }
    }
}
