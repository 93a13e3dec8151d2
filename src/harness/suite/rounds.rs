//! Matched-error rounds: after a dataset's rows and peers, each peer
//! renderer and the volbench run it is matched with (the fastest at no more
//! error, `Summary::matched_run`) run again, one after the other, in
//! `--rounds` rounds; the speed ratio is each round's, and the report gives
//! their median and spread. The first pass runs a dataset's rows in a minute
//! or more and each peer once, so a slow phase of a shared machine can hit
//! one side only; within a round the two runs are seconds apart, and the
//! rounds alternate which goes first, as `volbench ab` does for two builds.

use std::path::Path;
use std::sync::Arc;

use anyhow::{Context as _, Result};
use serde::Serialize;

use super::plan::{PlannedRun, Scene};
use super::summary::Summary;
use crate::harness::datasets::Dataset;
use crate::harness::peers::{self as pe, LocatedPeer, PeerDataset, PeerRow};
use crate::harness::run::{run, RunConfig};
use crate::harness::stats;
use crate::vk::Context;

/// One peer renderer against its matched volbench run, in rounds.
#[derive(Debug, Clone, Serialize)]
pub struct MatchedRounds {
    pub dataset: String,
    pub peer: String,
    pub renderer: String,
    /// The volbench run (`PlannedRun::label`): the fastest of the first pass
    /// whose RMSE against the f64 reference is no larger than the peer's.
    pub label: String,
    pub rounds: Vec<Round>,
    /// The rounds' speed ratios (peer ms / volbench ms): median, min, max.
    pub ratio: Option<stats::Summary>,
    /// Why a round did not complete (the rounds before it are kept).
    pub message: Option<String>,
}

/// One round: each side's median frame time, in the order they ran.
#[derive(Debug, Clone, Serialize)]
pub struct Round {
    pub volbench_ms: f64,
    pub peer_ms: f64,
    pub peer_first: bool,
}

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
pub(super) fn run_rounds(
    job: &RoundsJob,
    dataset: &mut Dataset,
    dataset_name: &str,
    summary: &mut Summary,
    progress: &mut dyn FnMut(&str),
) {
    let (Some(tf), Some(exported)) = (job.tf, job.exported) else { return };
    if job.rounds == 0 {
        return;
    }
    let pairs: Vec<(PeerRow, String)> = summary
        .peers
        .iter()
        .filter(|p| p.dataset == dataset_name && p.status == "ok")
        .filter_map(|p| Some((p.clone(), summary.matched_run(p)?.0.label.clone())))
        .collect();
    for (p, label) in pairs {
        let mut m = MatchedRounds {
            dataset: p.dataset.clone(),
            peer: p.peer.clone(),
            renderer: p.renderer.clone(),
            label: label.clone(),
            rounds: Vec::new(),
            ratio: None,
            message: None,
        };
        let planned = job.plan.iter().find(|r| r.dataset.name == dataset_name && r.scene == Scene::Standard && r.label() == label);
        let peer = job.located.iter().find(|l| l.peer.name == p.peer);
        let renderer = peer.and_then(|l| l.peer.renderers.iter().find(|r| r.name == p.renderer));
        let (Some(planned), Some(peer), Some(renderer)) = (planned, peer, renderer) else { continue };
        for k in 0..job.rounds {
            progress(&format!("round {}/{}: {label} against peer {}/{} on {dataset_name}", k + 1, job.rounds, p.peer, p.renderer));
            let side = Side { job, dataset: &mut *dataset, tf, planned, peer, renderer, exported };
            match side.round(k) {
                Ok(r) => m.rounds.push(r),
                Err(e) => {
                    m.message = Some(format!("round {}: {e:#}", k + 1));
                    break;
                }
            }
        }
        let ratios: Vec<f64> = m.rounds.iter().map(|r| r.peer_ms / r.volbench_ms).collect();
        m.ratio = (!ratios.is_empty()).then(|| stats::Summary::of(&ratios));
        summary.matched.push(m);
    }
}

/// Both sides of a round.
struct Side<'a, 'b> {
    job: &'a RoundsJob<'a>,
    dataset: &'b mut Dataset,
    tf: &'a crate::scene::TransferFunction,
    planned: &'a PlannedRun,
    peer: &'a LocatedPeer,
    renderer: &'static pe::PeerRenderer,
    exported: &'a PeerDataset,
}

impl Side<'_, '_> {
    /// Round `k`: volbench's run first in even rounds, the peer's in odd ones.
    fn round(mut self, k: usize) -> Result<Round> {
        let peer_first = k % 2 == 1;
        let peer_ms = if peer_first { Some(self.peer_ms(k)?) } else { None };
        let volbench_ms = self.volbench_ms()?;
        let peer_ms = match peer_ms {
            Some(ms) => ms,
            None => self.peer_ms(k)?,
        };
        anyhow::ensure!(volbench_ms > 0.0 && peer_ms > 0.0, "a frame time of 0 ms (volbench {volbench_ms}, peer {peer_ms})");
        Ok(Round { volbench_ms, peer_ms, peer_first })
    }

    /// The matched run's median frame time (no image written: the first
    /// pass has its record; no diagnostics: only the time is wanted).
    fn volbench_ms(&mut self) -> Result<f64> {
        let p = self.planned;
        let cfg = RunConfig { diagnostics: false, ..p.scene.config(self.job.cfg) };
        let r = self.dataset.run_handing_over(|d| run(self.job.ctx, &p.spec, d, self.tf, &cfg))??;
        Ok(r.result.time_ms.phase("frame").median)
    }

    /// The peer's median frame time; its files are named for the round and
    /// its image (only the transport) removed.
    fn peer_ms(&self, k: usize) -> Result<f64> {
        let mut scene = pe::scene(self.peer.peer, self.renderer, self.dataset, self.tf, self.job.cfg, self.exported, self.job.peers_dir)?;
        let stem = format!("{}-round{}", scene.stem(), k + 1);
        let dir = self.job.peers_dir;
        scene.output.result = dir.join(format!("{stem}.json")).to_string_lossy().into_owned();
        scene.output.image = dir.join(format!("{stem}.rgba")).to_string_lossy().into_owned();
        let scene_path = dir.join(format!("{stem}.scene.json"));
        let outcome = pe::run_peer(self.peer, &scene, &scene_path);
        // The first pass's scene is the record (this one differs only in
        // its output names); the result file stays.
        let _ = std::fs::remove_file(&scene.output.image);
        let _ = std::fs::remove_file(&scene_path);
        let (result, _) = outcome.with_context(|| format!("peer {}/{}", self.peer.peer.name, self.renderer.name))?;
        Ok(stats::Summary::of(&result.frame_ms).median)
    }
}
