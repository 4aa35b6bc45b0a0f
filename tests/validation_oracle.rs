//! The validation oracle cannot report "clean" for a run it did not check: a validated context
//! says validation ran, a context without the layers says it did not, and `assert_clean` refuses
//! the latter.

mod common;

use penumbra::{Context, ContextDesc};

#[test]
fn a_validated_context_reports_that_validation_ran() {
    let ctx = common::context();
    let log = ctx.validation();
    assert!(log.ran());
    assert!(log.counts().ran);
    drop(ctx);
    common::assert_clean(&log);
}

#[test]
fn a_context_without_validation_cannot_be_called_clean() {
    let ctx = Context::new(&ContextDesc {
        validation: false,
        device: None,
        ..Default::default()
    })
    .expect("context without validation");
    let log = ctx.validation();
    let counts = log.counts();
    assert!(
        !counts.ran,
        "no layer was enabled, yet the log claims it ran"
    );
    assert_eq!((counts.errors, counts.warnings), (0, 0));
    assert!(
        !counts.clean(),
        "zero counts of a run without layers are not clean"
    );
    let refused = std::panic::catch_unwind(|| common::assert_clean(&log));
    assert!(
        refused.is_err(),
        "assert_clean accepted a run without validation"
    );
}
