//! Matched-error rounds: after a dataset's rows and peers, each peer
//! renderer runs again with the volbench runs it may be matched with (the
//! two fastest of the first pass at no more error, `Summary::matched_runs`)
//! in `--rounds` rounds: the first run, the peer, the second, the order
//! reversed every other round (so with three rounds the first run precedes
//! the peer twice). Each run's ratio is its rounds' median; the report
//! quotes the better run's and gives the other beside it.
//!
//! Why: the first pass runs a dataset's rows in a minute or more and each
//! peer once, so a slow phase of a shared machine can hit one side only,
//! and the fastest run of one noisy pass is not reliably the fastest one;
//! within a round the runs are seconds apart.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context as _, Result};

use super::plan::{PlannedRun, Scene};
use super::summary::{MatchedRounds, Round, Summary};
use crate::harness::datasets::Dataset;
use crate::harness::peers::{self as pe, LocatedPeer, PeerDataset, PeerRow};
use crate::harness::run::{run, RunConfig};
use crate::harness::stats;
use crate::vk::Context;

/// The volbench runs measured against one peer renderer per round.
const CANDIDATES: usize = 2;

/// What the rounds of one dataset need: where the runs and the peers run,
/// the dataset's standard transfer function and its copy for the peers
/// (`None`: the first pass could not make them, and its rows say why).
pub(super) struct RoundsJob<'a> {
    pub ctx: &'a Arc<Context>,
    pub plan: &'a [PlannedRun],
    pub cfg: &'a RunConfig,
    pub rounds: usize,
    pub peers_dir: &'a Path,
    pub located: &'a [LocatedPeer],
    pub tf: Option<&'a crate::scene::TransferFunction>,
    pub exported: Option<&'a PeerDataset>,
}

/// The rounds of every peer row of `dataset_name` that ran and has a
/// matched run, appended to `summary.matched`; `progress` is told each.
pub(super) fn run_rounds(job: &RoundsJob, dataset: &mut Dataset, dataset_name: &str, summary: &mut Summary, progress: &mut dyn FnMut(&str)) {
    let (Some(tf), Some(exported)) = (job.tf, job.exported) else { return };
    if job.rounds == 0 {
        return;
    }
    let pairs: Vec<(PeerRow, Vec<String>)> = summary
        .peers
        .iter()
        .filter(|p| p.dataset == dataset_name && p.status == "ok")
        .map(|p| (p.clone(), summary.matched_runs(p).iter().take(CANDIDATES).map(|(r, _, _)| r.label.clone()).collect::<Vec<_>>()))
        .filter(|(_, labels)| !labels.is_empty())
        .collect();
    for (p, labels) in pairs {
        let planned: Option<Vec<&PlannedRun>> = labels
            .iter()
            .map(|l| job.plan.iter().find(|r| r.dataset.name == dataset_name && r.scene == Scene::Standard && r.label() == *l))
            .collect();
        let peer = job.located.iter().find(|l| l.peer.name == p.peer);
        let renderer = peer.and_then(|l| l.peer.renderers.iter().find(|r| r.name == p.renderer));
        let mut m = MatchedRounds {
            dataset: p.dataset.clone(),
            peer: p.peer.clone(),
            renderer: p.renderer.clone(),
            labels,
            rounds: Vec::new(),
            ratios: Vec::new(),
            best: None,
            message: None,
        };
        let (Some(planned), Some(peer), Some(renderer)) = (planned, peer, renderer) else {
            m.message = Some("internal: a matched run or the peer renderer was not found in the plan".into());
            summary.matched.push(m);
            continue;
        };
        for k in 0..job.rounds {
            progress(&format!("round {}/{}: {} against peer {}/{} on {dataset_name}", k + 1, job.rounds, m.labels.join(" and "), p.peer, p.renderer));
            let mut sides = Sides { job, dataset: &mut *dataset, tf, planned: &planned, peer, renderer, exported };
            match sides.round(k) {
                Ok(r) => m.rounds.push(r),
                Err(e) => {
                    m.message = Some(format!("round {}: {e:#}", k + 1));
                    break;
                }
            }
        }
        if !m.rounds.is_empty() {
            m.ratios = (0..m.labels.len())
                .map(|i| stats::Summary::of(&m.rounds.iter().map(|r| r.peer_ms / r.volbench_ms[i]).collect::<Vec<_>>()))
                .collect();
            m.best = (0..m.ratios.len()).max_by(|&a, &b| m.ratios[a].median.total_cmp(&m.ratios[b].median));
        }
        summary.matched.push(m);
    }
}

/// The runs of a round.
struct Sides<'a, 'b> {
    job: &'a RoundsJob<'a>,
    dataset: &'b mut Dataset,
    tf: &'a crate::scene::TransferFunction,
    planned: &'a [&'a PlannedRun],
    peer: &'a LocatedPeer,
    renderer: &'static pe::PeerRenderer,
    exported: &'a PeerDataset,
}

impl Sides<'_, '_> {
    /// Round `k`: the first label, the peer, the second label; odd rounds
    /// the reverse (one label: it and the peer, alternating who is first).
    fn round(&mut self, k: usize) -> Result<Round> {
        let reversed = k % 2 == 1;
        let n = self.planned.len();
        let mut order: Vec<Option<usize>> = (0..n).map(Some).collect();
        order.insert(order.len().min(1), None);
        if reversed {
            order.reverse();
        }
        let mut volbench_ms = vec![0.0; n];
        let mut peer_ms = 0.0;
        for side in order {
            match side {
                Some(i) => volbench_ms[i] = self.volbench_ms(self.planned[i])?,
                None => peer_ms = self.peer_ms(k)?,
            }
        }
        anyhow::ensure!(peer_ms > 0.0 && volbench_ms.iter().all(|&ms| ms > 0.0), "a frame time of 0 ms (volbench {volbench_ms:?}, peer {peer_ms})");
        Ok(Round { peer_ms, volbench_ms, reversed })
    }

    /// A run's median frame time (no image written: the first pass has its
    /// record; no diagnostics: only the time is wanted).
    fn volbench_ms(&mut self, p: &PlannedRun) -> Result<f64> {
        let cfg = RunConfig { diagnostics: false, ..p.scene.config(self.job.cfg) };
        let r = self.dataset.run_handing_over(|d| run(self.job.ctx, &p.spec, d, self.tf, &cfg))??;
        Ok(r.result.time_ms.phase("frame").median)
    }

    /// The peer's median frame time. Its files are named for the round (a
    /// result left by an earlier suite in the same folder removed first);
    /// its image (only the transport) is removed, and its scene too unless
    /// the round failed (the first pass's scene is the record: this one
    /// differs only in its output names).
    fn peer_ms(&self, k: usize) -> Result<f64> {
        let dir = self.job.peers_dir;
        let mut scene = pe::scene(self.peer.peer, self.renderer, self.dataset, self.tf, self.job.cfg, self.exported, dir)?;
        let stem = format!("{}-round{}", scene.stem(), k + 1);
        scene.output = pe::PeerOutput::in_dir(dir, &stem);
        let scene_path = dir.join(format!("{stem}.scene.json"));
        let _ = std::fs::remove_file(&scene.output.result);
        let outcome = pe::run_peer(self.peer, &scene, &scene_path);
        let _ = std::fs::remove_file(&scene.output.image);
        if outcome.is_ok() {
            let _ = std::fs::remove_file(&scene_path);
        }
        let (result, _) = outcome.with_context(|| format!("peer {}/{}", self.peer.peer.name, self.renderer.name))?;
        Ok(stats::Summary::of(&result.frame_ms).median)
    }
}
