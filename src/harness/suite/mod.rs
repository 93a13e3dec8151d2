//! `volbench suite`: every registered method on every shipped dataset of its
//! kind (or on the datasets `--data` lists: shipped names, users' files) at
//! standard settings, one command, one folder a researcher can cite:
//! `summary.json` (every run in the common schema plus the environment),
//! `summary.csv`, `report.md`, plots (PNG and SVG) and a montage of the
//! rendered images with their difference from the f64 reference. A failing
//! row is recorded and the suite goes on; a method the device cannot run is
//! recorded as skipped. Nothing here names a method: the plan is the
//! registry crossed with the datasets.
//!
//! One job per file: `plan.rs` (what to run), `run.rs` (running it),
//! `rounds.rs` (each peer again with the runs it may be matched with), `summary.rs`
//! (what `summary.json` and `summary.csv` hold), `report.rs` (`report.md` and
//! the pictures).

mod plan;
mod report;
mod rounds;
mod run;
mod summary;

pub use plan::{plan, PlannedRun, Scene, SuiteDataset, SuiteSettings, CULL_SCENE_DATASETS, ZOOM};
pub use report::{cull_report, peer_report, report};
pub use run::run_suite;
pub use summary::{csv, machine_boot_id, parse_utc, utc_now, CullCheck, Environment, MatchedRounds, Round, SuiteDatasetRow, SuiteRow, Summary};
