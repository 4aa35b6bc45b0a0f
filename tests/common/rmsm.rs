//! Helpers of the `rmsm` tests (`tests/rmsm*.rs`): its knobs over the kernel-only ones, one frame
//! with everything read back from its pages, and a scene prepared at test size.

use std::collections::BTreeMap;

use penumbra::engine::PreparedScene;
use penumbra::{Engine, Frame};

/// Everything a test reads back from one frame.
pub struct Run {
    pub frame: Frame,
    pub list: Vec<u32>,
    pub refine_list: Vec<u32>,
    pub table: Vec<u32>,
    pub bins: Vec<(u32, u32)>,
    pub slots: Vec<[u32; 4]>,
}

/// `set` over the kernel-only knobs, with pages of 128², requests matched to the screen
/// (`lod_bias` 0) and no refinement round unless `set` says otherwise (the twin's request and
/// allocation rules describe round 0; `refinement_*` covers round 1).
pub fn knobs(set: &[(&str, &str)]) -> BTreeMap<String, String> {
    let mut m = super::knobs(set);
    for (k, v) in [("refine", "0"), ("page_size", "128"), ("lod_bias", "0")] {
        m.entry(k.into()).or_insert(v.into());
    }
    for (k, v) in super::KERNEL_ONLY {
        m.entry(k.into()).or_insert(v.to_string());
    }
    m
}

pub fn run(engine: &Engine, prepared: &PreparedScene, set: &[(&str, &str)]) -> Run {
    let (mut list, mut table, mut bins, mut slots) = (vec![], vec![], vec![], vec![]);
    let mut refine_list = vec![];
    let frame = engine
        .render_inspect(prepared, "rmsm", &knobs(set), 1, |t| {
            let pages = t.virtual_pages().expect("rmsm has pages");
            list = pages.read_page_list()?;
            refine_list = pages.read_refine_list()?;
            table = pages.read_table()?;
            bins = pages.read_bins()?;
            slots = pages.read_slots()?;
            Ok(())
        })
        .expect("render");
    super::assert_clean(&engine.context().validation());
    assert_eq!(frame.stats.nan_count, 0, "NaN with {set:?}");
    assert_eq!(
        frame.stats.out_of_range_count, 0,
        "V outside [0,1] with {set:?}"
    );
    Run {
        frame,
        list,
        refine_list,
        table,
        bins,
        slots,
    }
}

pub fn prepare(engine: &Engine, spec: &str) -> PreparedScene {
    engine.prepare(&super::small(spec)).expect("prepare")
}
