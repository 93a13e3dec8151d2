//! What the suite runs: its settings (standard or `--quick`), the scenes a
//! run may be seen in, and the plan — the registry crossed with the shipped
//! datasets, filtered, with each method's published and suite option sets
//! and the culling scenes.

use anyhow::Result;
use serde::Serialize;

use crate::algo::registry::{MethodSpec, Registry};
use crate::harness::datasets::{self, Dataset};
use crate::harness::run::RunConfig;

/// How the suite runs: standard settings, or `--quick` ones.
#[derive(Debug, Clone, Serialize)]
pub struct SuiteSettings {
    pub width: u32,
    pub height: u32,
    pub frames: usize,
    pub warmup: usize,
    pub orbit_step_deg: f64,
    pub quick: bool,
    /// Only runs whose method or dataset name is listed (empty: all).
    pub filter: Vec<String>,
    /// Peers (`--peers`, see `harness::peers`) run on the same datasets,
    /// alternating with volbench's runs.
    pub peers: Vec<String>,
    /// Counted (`--count`): each run counts its timed frames' instructions
    /// (`harness::count`); no CPU reference, no diagnostics.
    pub counted: bool,
    /// The counted child's dump directory.
    #[serde(skip)]
    pub count_dir: Option<std::path::PathBuf>,
    /// How a mesh file's cell array is shown (`--cell-data`; each run's
    /// `dataset.stats` records it).
    #[serde(skip)]
    pub cell_data: crate::mesh::cell_data::CellData,
}

impl SuiteSettings {
    pub fn standard(quick: bool, filter: Vec<String>) -> Self {
        if quick {
            SuiteSettings { width: 256, height: 256, frames: 3, warmup: 1, orbit_step_deg: 5.0, quick, filter, peers: Vec::new(), counted: false, count_dir: None, cell_data: Default::default() }
        } else {
            SuiteSettings { width: 512, height: 512, frames: 20, warmup: 3, orbit_step_deg: 5.0, quick, filter, peers: Vec::new(), counted: false, count_dir: None, cell_data: Default::default() }
        }
    }

    /// The counted suite (`--count`): the quick one at 64x64 and 2 timed
    /// frames (a count repeats without many samples; CI's budget).
    pub fn counted(mut self, count_dir: Option<std::path::PathBuf>) -> Self {
        if count_dir.is_some() {
            if self.quick {
                (self.width, self.height, self.frames, self.warmup) = (64, 64, 2, 1);
            }
            self.counted = true;
            self.count_dir = count_dir;
        }
        self
    }

    pub(super) fn run_config(&self) -> RunConfig {
        RunConfig {
            width: self.width,
            height: self.height,
            frames: self.frames,
            warmup: self.warmup,
            orbit_step: self.orbit_step_deg.to_radians(),
            diagnostics: self.count_dir.is_none(),
            overlap: self.count_dir.is_none(),
            count_dir: self.count_dir.clone(),
            ..RunConfig::default()
        }
    }
}

/// One planned run: a shipped dataset and a method at its defaults, or with
/// an option set a published figure names; or a culling scene.
#[derive(Debug)]
pub struct PlannedRun {
    pub dataset: &'static str,
    pub spec: MethodSpec,
    pub scene: Scene,
}

impl PlannedRun {
    /// How the run is named in rows and reports: the spec's label, and the
    /// scene when it is not the standard one (`balanced:cull=off @zoomed`).
    pub fn label(&self) -> String {
        match self.scene {
            Scene::Standard => self.spec.label(),
            s => format!("{} @{}", self.spec.label(), s.name()),
        }
    }

    /// The montage a run's image goes to: its dataset, and the scene when
    /// it is not the standard one (another view, another reference).
    pub(super) fn montage_group(&self) -> String {
        match self.scene {
            Scene::Standard => self.dataset.to_string(),
            s => format!("{}@{}", self.dataset, s.name()),
        }
    }

    pub(super) fn file_stem(&self) -> String {
        match self.scene {
            Scene::Standard => self.spec.file_stem(),
            s => format!("{}@{}", self.spec.file_stem(), s.name()),
        }
    }
}

/// The view and transfer function of a run: the standard orbit with the
/// dataset's preset, or one of the scenes where culling matters
/// (`algo::cell_projection::cull`), each run with culling on and off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Scene {
    Standard,
    /// The dataset's `<name>-band` transfer function (`data/tf/`): opaque
    /// only in a narrow band of the scalar range, most cells transparent.
    Transparent,
    /// The orbit zoomed in [`ZOOM`] times (`RunConfig::zoom`: aimed off
    /// the centre): most cells off-screen.
    Zoomed,
    /// The orbit's first view for every frame.
    Still,
}

/// The zoomed scene's factor.
pub const ZOOM: f64 = 4.0;

/// The datasets the culling scenes run on (the oxygen post: its preset and
/// its `oxygenpost-band` transfer function).
pub const CULL_SCENE_DATASETS: &[&str] = &["oxygenpost"];

impl Scene {
    pub const CULLING: [Scene; 3] = [Scene::Transparent, Scene::Zoomed, Scene::Still];

    pub fn name(self) -> &'static str {
        match self {
            Scene::Standard => "standard",
            Scene::Transparent => "transparent",
            Scene::Zoomed => "zoomed",
            Scene::Still => "still",
        }
    }

    /// The run configuration of this scene from the suite's.
    pub(super) fn config(self, cfg: &RunConfig) -> RunConfig {
        match self {
            Scene::Standard | Scene::Transparent => cfg.clone(),
            // Its magnified cells make a frame several times a standard
            // one: a third of the timed frames keeps the suite's budget.
            Scene::Zoomed => RunConfig { zoom: ZOOM, frames: (cfg.frames / 3).max(1), ..cfg.clone() },
            Scene::Still => RunConfig { orbit_step: 0.0, ..cfg.clone() },
        }
    }

    /// The transfer function of this scene on `dataset`.
    pub(super) fn transfer_function(self, dataset: &Dataset) -> Result<crate::scene::TransferFunction> {
        match self {
            Scene::Transparent => {
                let path = crate::data_dir::data_dir().join("tf").join(format!("{}-band.json", dataset.name));
                dataset.load_transfer_function(&path)
            }
            _ => dataset.default_transfer_function(),
        }
    }
}

/// Every (shipped dataset, method for its kind) pair that passes the
/// filter: the defaults, then each option set a published figure about the
/// method on that dataset names (so every published ratio has its measured
/// counterpart in the same run), then the method's own suite sets
/// (`MethodInfo::suite`: the cheap end of its accuracy trade-off).
pub fn plan(registry: &Registry, settings: &SuiteSettings) -> Result<Vec<PlannedRun>> {
    let keep = |name: &str| settings.filter.is_empty() || settings.filter.iter().any(|f| f == name);
    for f in &settings.filter {
        let known = datasets::NAMED.iter().any(|d| d.name == f) || registry.names().contains(&f.as_str());
        anyhow::ensure!(known, "--filter {f}: neither a registered method nor a shipped dataset (see `volbench list`)");
    }
    let mut out = Vec::new();
    for d in datasets::NAMED {
        for m in registry.for_kind(d.kind) {
            if keep(d.name) || keep(m.name) {
                let mut specs = vec![registry.parse_spec(m.name, &[])?];
                let published = m.published.iter().filter(|p| p.applies_to(d.name)).map(|p| registry.published_spec(p));
                let own = m.suite.iter().map(|o| registry.parse_spec(&format!("{}:{o}", m.name), &[]));
                for s in published.chain(own) {
                    let s = s?;
                    if !specs.iter().any(|x| x.canonical() == s.canonical()) {
                        specs.push(s);
                    }
                }
                out.extend(specs.into_iter().map(|spec| PlannedRun { dataset: d.name, spec, scene: Scene::Standard }));
            }
        }
        // The culling scenes: the first methods with their family's culling
        // option (`Family::culling_option`: the papers' VICP and balanced;
        // --quick: the first only), culling on and off (the unchanged-image
        // check and the speed-up). Every method culls alike (tests/cull.rs);
        // more would not fit the suite's budget.
        if CULL_SCENE_DATASETS.contains(&d.name) {
            let culling: Vec<_> = registry
                .for_kind(d.kind)
                .filter(|m| (keep(d.name) || keep(m.name)) && m.culling_option().is_some())
                .take(if settings.quick { 1 } else { 2 })
                .collect();
            // --quick leaves out the zoomed scene: magnified cells cost many
            // more fragments (the CI budget).
            for scene in Scene::CULLING.into_iter().filter(|&s| !(settings.quick && s == Scene::Zoomed)) {
                for m in &culling {
                    let option = m.culling_option().unwrap_or_default();
                    for cull in ["on", "off"] {
                        let spec = registry.parse_spec(&format!("{}:{option}={cull}", m.name), &[])?;
                        out.push(PlannedRun { dataset: d.name, spec, scene });
                    }
                }
            }
        }
    }
    anyhow::ensure!(!out.is_empty(), "--filter {:?} leaves nothing to run", settings.filter);
    // A peer that is not installed is an error before anything runs.
    for p in &settings.peers {
        crate::harness::peers::locate(p)?;
    }
    Ok(out)
}
