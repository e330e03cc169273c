//! `dualstream report`: what it needs is named when missing.

use crate::fails_with;

#[test]
fn report_paper_names_missing_scenes() {
    fails_with(
        &["report", "paper", "--scenes-dir", "/nonexistent"],
        &["dragon.toml", "shared/scenes"],
    );
    fails_with(&["report", "nonsense"], &["unknown report"]);
}
