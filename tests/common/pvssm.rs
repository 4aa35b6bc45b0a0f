//! Helpers of the `pvssm` tests (`tests/pvssm*.rs`): a frame with its checks, counters, and a
//! scene scored against its reference.

use penumbra::engine::PreparedScene;
use penumbra::{Engine, Frame};

use super::knobs;

/// `pvssm` with the knobs `set`, one frame, checked for NaN, values outside [0, 1] and any
/// validation message so far.
pub fn render(engine: &Engine, prepared: &PreparedScene, set: &[(&str, &str)]) -> Frame {
    let frame = engine
        .render(prepared, "pvssm", &knobs(set), 1)
        .expect("render");
    super::assert_clean(&engine.context().validation());
    assert_eq!(frame.stats.nan_count, 0, "NaN with {set:?}");
    assert_eq!(
        frame.stats.out_of_range_count, 0,
        "V outside [0,1] with {set:?}"
    );
    frame
}

/// A bundled scene at test size, its 8 × 8-sample reference and which pixels are view samples:
/// what the tests that score `pvssm` against the reference share.
pub struct Scored {
    pub prepared: PreparedScene,
    pub reference: Frame,
    pub is_sample: Vec<bool>,
}

impl Scored {
    pub fn new(engine: &Engine, scene: &str) -> Scored {
        Scored::of(engine, &super::small(scene), 8)
    }

    /// `scene` and its reference of `samples`² light samples.
    pub fn of(engine: &Engine, scene: &penumbra::scene::Scene, samples: u32) -> Scored {
        let prepared = engine.prepare(scene).expect("prepare");
        let positions = prepared
            .view
            .read_positions(engine.context())
            .expect("positions");
        let is_sample = positions.iter().map(|p| p.w > 0.0).collect();
        let samples = samples.to_string();
        let reference = engine
            .render(&prepared, "reference", &knobs(&[("samples", &samples)]), 1)
            .expect("reference");
        super::assert_clean(&engine.context().validation());
        Scored {
            prepared,
            reference,
            is_sample,
        }
    }

    /// `pvssm` with the knobs `set` against the reference, and its frame.
    pub fn score(
        &self,
        engine: &Engine,
        set: &[(&str, &str)],
    ) -> (penumbra::metrics::ErrorMetrics, Frame) {
        let frame = render(engine, &self.prepared, set);
        let metrics = penumbra::metrics::compare(
            &self.reference.visibility,
            &frame.visibility,
            &self.is_sample,
        )
        .expect("metrics");
        (metrics, frame)
    }

    /// `pvssm`'s penumbra MAE against the reference with the knobs `set`.
    pub fn penumbra_mae(&self, engine: &Engine, set: &[(&str, &str)]) -> f64 {
        self.score(engine, set)
            .0
            .penumbra_mae
            .expect("the scene has a penumbra")
    }
}
