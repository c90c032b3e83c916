//! `[occlusion]`: pattern files and generator requests.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use crate::error::Result;
use crate::occlusion::{self, Occlusion, Scenario, Style};
use crate::toml_input::{steps, KeyLocator};

use super::schema::OcclusionFile;

/// Most occluders one generator request may make.
const MAX_GENERATE_COUNT: usize = 1_000_000;

/// A generator request: `count` random occlusions of a scenario.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GenerateRequest {
    /// Scenario.
    pub scenario: Scenario,
    /// Exact coverage of each.
    pub coverage: f64,
    /// How many.
    pub count: usize,
    /// Look (random per occluder when `None`).
    pub style: Option<Style>,
}

/// The occlusions of a dataset: fixed patterns and generated ones.
#[derive(Debug, Clone, Default)]
pub struct OcclusionSet {
    /// Patterns read from files, in order.
    pub patterns: Vec<Arc<Occlusion>>,
    /// Pattern file of each, relative to the spec's directory as written.
    pub pattern_files: Vec<PathBuf>,
    /// Generator requests.
    pub generate: Vec<GenerateRequest>,
}

impl OcclusionSet {
    /// Number of occlusion variants (one image each per sweep value).
    #[must_use]
    pub fn len(&self) -> usize {
        self.patterns.len() + self.generate.iter().map(|g| g.count).sum::<usize>()
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The validated occlusion set of `of`; pattern paths are relative to
/// `base_dir`.
pub(super) fn occlusion_set(
    loc: &KeyLocator,
    of: &OcclusionFile,
    base_dir: &Path,
) -> Result<OcclusionSet> {
    let mut occl = OcclusionSet::default();
    for (i, p) in of.patterns.iter().enumerate() {
        let full = base_dir.join(p);
        let files = occlusion::pattern_files(&full).map_err(|e| {
            loc.err(
                steps!["occlusion", "patterns", i],
                format!("occlusion.patterns: {e}"),
            )
        })?;
        for f in files {
            let mut occ = Occlusion::load(&f)?;
            if let Some(style) = of.style {
                for oc in &mut occ.occluders {
                    oc.appearance = style.appearance();
                }
            }
            let shown = p.join(f.file_name().unwrap_or_default());
            occl.pattern_files
                .push(if full.is_dir() { shown } else { p.clone() });
            occl.patterns.push(Arc::new(occ));
        }
    }
    for (i, gf) in of.generate.iter().enumerate() {
        let max = occlusion::max_coverage(gf.scenario);
        if !(gf.coverage > 0.0 && gf.coverage <= max) {
            return Err(loc.err(
                steps!["occlusion", "generate", i, "coverage"],
                format!(
                    "occlusion.generate: coverage {} is outside (0, {max}] for scenario {}",
                    gf.coverage,
                    gf.scenario.name()
                ),
            ));
        }
        if gf.count == 0 || gf.count > MAX_GENERATE_COUNT {
            return Err(loc.err(
                steps!["occlusion", "generate", i, "count"],
                format!(
                    "occlusion.generate: count {} is outside 1..={MAX_GENERATE_COUNT}",
                    gf.count
                ),
            ));
        }
        occl.generate.push(GenerateRequest {
            scenario: gf.scenario,
            coverage: gf.coverage,
            count: gf.count,
            style: gf.style.or(of.style),
        });
    }
    if occl.is_empty() {
        return Err(loc.err(
            steps!["occlusion"],
            "occlusion: give patterns or generate".into(),
        ));
    }
    Ok(occl)
}
