//! Splitting a run over machines, and putting the pieces back together.
//!
//! Shard `K/N` of a dataset is every image whose index `i` has
//! `i % N == K`: a fixed slice that depends on nothing but the index, so
//! any machine computes the same one, shards never overlap and together
//! they cover the dataset. A shard's run log records `K/N`
//! ([`crate::runner::RunInfo::shard`]); [`merge`] puts the `N` logs of one
//! detector on one dataset back into the log the unsharded run would have
//! written: the same per-image messages in index order. Every metric
//! computed from detections and per-image times is therefore exactly the
//! unsharded one. Resource totals are merged as sums (images, errors, CPU
//! and wall seconds: CPU share = total CPU over total wall time) and the
//! largest peak memory, the only meaningful merge of measurements made by
//! separate processes.
//!
//! The shards' datasets may be one shared directory (every task reads the
//! whole set and runs its slice) or one directory per shard (each task
//! rendered its own slice with `coppertag synth --shard`): [`merge`] takes
//! the union of their ground truth.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::error::{EvalError, Result};
use crate::runlog::{DetectionsMessage, RunLog};
use crate::truth::Dataset;

/// Shard `index` of `count`: the images with `image_index % count == index`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Shard {
    /// K, from 0.
    pub index: usize,
    /// N, at least 1.
    pub count: usize,
}

impl Shard {
    /// Whether image `image_index` belongs to this shard.
    pub fn contains(&self, image_index: usize) -> bool {
        image_index % self.count == self.index
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for Shard {
    type Err = EvalError;

    /// Parses `K/N` with `0 <= K < N`.
    fn from_str(s: &str) -> Result<Self> {
        let bad = |reason: String| EvalError::InvalidParameter {
            name: "shard",
            reason,
        };
        let (k, n) = s
            .split_once('/')
            .ok_or_else(|| bad(format!("{s:?} is not K/N (for example 0/8)")))?;
        let parse = |v: &str, what: &str| {
            v.trim()
                .parse::<usize>()
                .map_err(|_| bad(format!("{s:?}: {what} {v:?} is not a whole number")))
        };
        let (index, count) = (parse(k, "K")?, parse(n, "N")?);
        if count == 0 {
            return Err(bad(format!("{s:?}: N must be at least 1")));
        }
        if index >= count {
            return Err(bad(format!("{s:?}: K must be below N (0..={})", count - 1)));
        }
        Ok(Self { index, count })
    }
}

/// Keeps only the images of `dataset` that belong to `shard` (ground truth
/// of other images stays, unused).
pub fn restrict(dataset: &mut Dataset, shard: Shard) {
    dataset.images.retain(|(i, _)| shard.contains(*i));
}

/// The union of the shards' datasets: images and ground truth of every
/// part. Parts must be slices of one dataset (same name; an image index
/// names the same file everywhere); the first part's directory is kept.
pub fn union(parts: &[Dataset]) -> Result<Dataset> {
    let first = parts.first().ok_or_else(|| EvalError::InvalidParameter {
        name: "shards",
        reason: "no datasets to merge".into(),
    })?;
    let mut images: BTreeMap<usize, String> = BTreeMap::new();
    let mut truth = BTreeMap::new();
    for d in parts {
        if d.name != first.name {
            return Err(EvalError::bad(
                &d.dir,
                format!(
                    "shard dataset {:?} is not a slice of {:?}",
                    d.name, first.name
                ),
            ));
        }
        for (i, file) in &d.images {
            if let Some(prev) = images.insert(*i, file.clone()) {
                if &prev != file {
                    return Err(EvalError::bad(
                        &d.dir,
                        format!("image {i} is {file} here but {prev} in another shard"),
                    ));
                }
            }
        }
        for (file, rows) in &d.truth {
            truth.entry(file.clone()).or_insert_with(|| rows.clone());
        }
    }
    Ok(Dataset {
        dir: first.dir.clone(),
        name: first.name.clone(),
        images: images.into_iter().collect(),
        truth,
    })
}

/// Merges the logs of the shards `0/N .. N-1/N` of one detector on one
/// dataset into the log of the unsharded run. Every shard must be present
/// exactly once, with the same detector, version and parameters, and no
/// image may appear twice.
pub fn merge(mut parts: Vec<RunLog>) -> Result<RunLog> {
    let bad = |reason: String| EvalError::InvalidParameter {
        name: "shards",
        reason,
    };
    let shards: Vec<Shard> = parts
        .iter()
        .map(|p| {
            p.info
                .shard
                .parse::<Shard>()
                .map_err(|_| bad(format!("run of {} is not a shard", p.info.dataset)))
        })
        .collect::<Result<_>>()?;
    let Some(n) = shards.first().map(|s| s.count) else {
        return Err(bad("no runs to merge".into()));
    };
    let label = format!("{} on {}", parts[0].info.detector, parts[0].info.dataset);
    let what = || label.as_str();
    let mut seen = vec![false; n];
    for s in &shards {
        if s.count != n {
            return Err(bad(format!(
                "{}: shards of {n} and of {} mixed",
                what(),
                s.count
            )));
        }
        if std::mem::replace(&mut seen[s.index], true) {
            return Err(bad(format!("{}: shard {s} given twice", what())));
        }
    }
    let missing: Vec<String> = (0..n)
        .filter(|&k| !seen[k])
        .map(|k| format!("{k}/{n}"))
        .collect();
    if !missing.is_empty() {
        return Err(bad(format!(
            "{}: missing shard(s) {}",
            what(),
            missing.join(", ")
        )));
    }
    for p in &parts[1..] {
        let (a, b) = (&parts[0].info, &p.info);
        if (&a.detector, &a.version, &a.parameters, &a.dataset)
            != (&b.detector, &b.version, &b.parameters, &b.dataset)
        {
            return Err(bad(format!(
                "{}: shard {} ran {} {} on {}, another {} {} on {}",
                what(),
                b.shard,
                b.detector,
                b.version,
                b.dataset,
                a.detector,
                a.version,
                a.dataset
            )));
        }
    }
    // Shard order, then index order: sums below are then independent of
    // the order the logs were given in.
    let mut order: Vec<usize> = (0..parts.len()).collect();
    order.sort_by_key(|&i| shards[i].index);
    let mut images: Vec<DetectionsMessage> = Vec::new();
    let mut resources = crate::runner::RunResources::default();
    for &i in &order {
        resources.add(&parts[i].resources);
        images.append(&mut parts[i].images);
    }
    images.sort_by_key(|m| m.index);
    if let Some(w) = images.windows(2).find(|w| w[0].index == w[1].index) {
        return Err(bad(format!(
            "{}: image {} is in two shards",
            what(),
            w[0].index
        )));
    }
    let mut info = parts[order[0]].info.clone();
    info.shard = String::new();
    info.sessions = parts.iter().map(|p| p.info.sessions).max().unwrap_or(1);
    Ok(RunLog {
        info,
        resources,
        images,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_checks_k_over_n() {
        assert_eq!(
            "2/5".parse::<Shard>().unwrap(),
            Shard { index: 2, count: 5 }
        );
        for bad in ["5/5", "1/0", "x/3", "3", "-1/3", ""] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        let s = Shard { index: 1, count: 3 };
        let picked: Vec<usize> = (0..10).filter(|&i| s.contains(i)).collect();
        assert_eq!(picked, [1, 4, 7]);
        assert_eq!(s.to_string(), "1/3");
    }
}
