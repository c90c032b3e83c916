//! The "wild" section of `reports/README.md`: the sampled-scene benchmark's
//! table (a row per system), the detector issue's scenarios and its factor curves, each figure with a
//! sentence saying what it shows; CSVs beside them.

use std::fmt::Write as _;
use std::path::Path;

use crate::atomic::write_atomic_in_new_dir;
use crate::draws::FAMILY;
use crate::error::Result;
use crate::plot::{line_chart, Chart, Series};
use crate::pose_error::{FLIP_ROTATION_DEG, FLIP_SEPARATION_DEG};
use crate::sigma::{SigmaCoverage, SIGMA_MULTIPLE};
use crate::wild_scenarios::{
    scenarios_table, HEAVY_DEFOCUS_PX, HEAVY_MOTION_PX, SHARP_DEFOCUS_PX, SHARP_MOTION_PX,
};
use crate::wild_summary::{
    FactorCurve, WildSummary, JITTER_MIN_RENDERS, MIN_DETECTABLE_MARKERS, MIN_DETECTABLE_RATE,
};

/// The wild table's corner-error cell: median / p95 px of the corners a
/// system reports as observed, then of those it reports as estimated
/// ("-" where it flags none).
fn corner_error_cell(r: &crate::wild_summary::SystemRow) -> String {
    let part = |s: &crate::metrics::Stats| {
        if s.n == 0 {
            "-".to_string()
        } else {
            format!("{:.2} / {:.2}", s.median, s.p95)
        }
    };
    format!(
        "{}; {}",
        part(&r.corner_error_observed_px),
        part(&r.corner_error_estimated_px)
    )
}

fn display(system: &str) -> String {
    match system {
        "aruco3" => "ArUco3".into(),
        "apriltag3" => "AprilTag3".into(),
        "stag" => "STag".into(),
        "fractal" => "Fractal".into(),
        "coppertag" => "CopperTag".into(),
        other => other.into(),
    }
}

fn pct(v: f64) -> String {
    format!("{:.1}%", 100.0 * v)
}

fn num(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |x| format!("{x:.digits$}"))
}

/// What a factor is, for axis labels and captions.
fn describe(factor: &str) -> String {
    let known = match factor {
        "side_px" => "side of the marker square in the image (px)",
        "distance_m" => "distance to the camera (m)",
        "tilt_x_deg" => "tilt about the x axis (degrees)",
        "tilt_y_deg" => "tilt about the y axis (degrees)",
        "roll_deg" => "roll in the image plane (degrees)",
        "pos_x" => "horizontal position in the frame",
        "pos_y" => "vertical position in the frame",
        "contrast" => "print contrast",
        "clutter_density" => "background clutter density",
        "defocus_px" => "defocus blur (px)",
        "motion_blur_px" => "motion blur (px)",
        "read_noise_dn" => "sensor read noise (DN)",
        "jpeg_quality" => "JPEG quality (frames with a JPEG step)",
        "occluder_kind" => "occluder kind",
        "occluder_coverage" => "share of the marker square occluded",
        "markers_per_frame" => "markers per frame",
        _ => "",
    };
    if known.is_empty() {
        factor.replace('_', " ")
    } else {
        known.into()
    }
}

fn curve_figure(c: &FactorCurve, dir: &Path, out: &mut String) -> Result<()> {
    let mut series: Vec<Series> = Vec::new();
    for p in &c.points {
        let label = display(&p.system);
        if series.last().is_none_or(|s| s.label != label) {
            series.push(Series {
                label,
                points: Vec::new(),
            });
        }
        if let (Some(x), Some(s)) = (p.centre.filter(|_| p.markers > 0), series.last_mut()) {
            s.points.push((x, 100.0 * p.rate()));
        }
    }
    let stem = format!("wild-{}", c.factor);
    let what = describe(&c.factor);
    let reading = curve_reading(c);
    line_chart(
        &dir.join(&stem),
        &Chart {
            title: &format!("Detection rate against {what}"),
            x_label: &what,
            y_label: "found, correct or rough (%)",
            y_range: Some((0.0, 102.0)),
        },
        &series,
    )?;
    let _ = writeln!(
        out,
        "### {}\n\n![{stem}]({stem}.png)\n\nThe share of markers each system found (correct or rough) against the \
         {what}, one point per bin (bins hold about equally many markers; SVG beside it, bins, counts and \
         the rough share in `wild-factors.csv`). {reading}\n",
        c.factor
    );
    Ok(())
}

/// One sentence on what a curve shows: each system's rate in the lowest
/// and the highest bin of the factor.
fn curve_reading(c: &FactorCurve) -> String {
    let Some(bins) = &c.bins else {
        return String::new();
    };
    let mut parts = Vec::new();
    let mut systems: Vec<&str> = Vec::new();
    for p in &c.points {
        if !systems.contains(&p.system.as_str()) {
            systems.push(&p.system);
        }
    }
    for sys in systems {
        let pts: Vec<_> = c
            .points
            .iter()
            .filter(|p| p.system == sys && p.markers > 0)
            .collect();
        if let (Some(first), Some(last)) = (pts.first(), pts.last()) {
            parts.push(format!(
                "{} {} -> {}",
                display(sys),
                pct(first.rate()),
                pct(last.rate())
            ));
        }
    }
    if parts.is_empty() || bins.len() < 2 {
        return String::new();
    }
    let (lo, _) = bins.range(0);
    let (_, hi) = bins.range(bins.len() - 1);
    format!(
        "From the lowest bin (from {}) to the highest (to {}): {}.",
        short(lo),
        short(hi),
        parts.join(", ")
    )
}

fn short(v: f64) -> String {
    if v.abs() >= 100.0 || v == v.trunc() {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

/// False positives per megapixel, all tag-free sets and each.
fn fp_cell(r: &crate::wild_summary::SystemRow) -> String {
    let all = num(r.false_positives_per_mp, 3);
    if r.false_positives_per_mp_by_set.len() < 2 {
        return all;
    }
    let each: Vec<String> = r
        .false_positives_per_mp_by_set
        .iter()
        .map(|(k, v)| format!("{k} {v:.3}"))
        .collect();
    format!("{all} ({})", each.join(", "))
}

/// Time per frame, median / p95 / max (ms); "-" when the system's runs
/// were not timed (their detector sessions ran several at once, as in the
/// gate's quick run, which scores detection only).
fn time_cell(t: &crate::metrics::Stats) -> String {
    if t.n == 0 {
        return "-".into();
    }
    format!("{:.2} / {:.2} / {:.2}", t.median, t.p95, t.max)
}

/// Corners within 2 sigma: all, then (observed / estimated); "-" for a
/// system that reports no sigma, or for a split with no corners.
fn sigma_cell(c: Option<&SigmaCoverage>) -> String {
    let Some(c) = c else {
        return "-".into();
    };
    let share = |t: &crate::sigma::Tally| t.share().map_or("-".into(), pct);
    format!(
        "{} ({} / {})",
        share(&c.all),
        share(&c.observed),
        share(&c.estimated)
    )
}

fn category_table(c: &FactorCurve, out: &mut String) {
    let mut labels: Vec<&str> = c.points.iter().map(|p| p.label.as_str()).collect();
    labels.sort();
    labels.dedup();
    let mut systems: Vec<&str> = Vec::new();
    for p in &c.points {
        if !systems.contains(&p.system.as_str()) {
            systems.push(&p.system);
        }
    }
    let _ = writeln!(
        out,
        "### {}\n\nThe share of markers each system found (correct or rough) for each {}; n markers in brackets.\n",
        c.factor,
        describe(&c.factor)
    );
    let _ = writeln!(
        out,
        "| {} | {} |\n|---|{}",
        c.factor,
        systems
            .iter()
            .map(|s| display(s))
            .collect::<Vec<_>>()
            .join(" | "),
        "---|".repeat(systems.len())
    );
    for l in labels {
        let cells: Vec<String> = systems
            .iter()
            .map(|s| {
                c.points
                    .iter()
                    .find(|p| p.system == *s && p.label == l)
                    .map_or("-".into(), |p| format!("{} ({})", pct(p.rate()), p.markers))
            })
            .collect();
        let _ = writeln!(out, "| {l} | {} |", cells.join(" | "));
    }
    out.push('\n');
}

/// The within-2-sigma figure behind each system's cell: how many
/// detections it rests on, readings by code against readings by
/// likelihood, and each set; empty when no system reports a sigma.
fn sigma_sentence(w: &WildSummary) -> String {
    let mut parts = Vec::new();
    for r in &w.systems {
        let Some(c) = &r.corner_sigma else { continue };
        let share = |t: &crate::sigma::Tally| t.share().map_or("-".into(), pct);
        let sets: Vec<String> = r
            .corner_sigma_by_set
            .iter()
            .map(|(k, v)| format!("{k} {}", share(&v.all)))
            .collect();
        parts.push(format!(
            "{}: {} detections with a sigma ({} corners); read by code {}, by likelihood {}; {}",
            display(&r.system),
            c.detections,
            c.all.corners,
            share(&c.code),
            share(&c.likelihood),
            sets.join(", ")
        ));
    }
    if parts.is_empty() {
        String::new()
    } else {
        format!(" {}.", parts.join(". "))
    }
}

/// The table of one set's system rows (the wild set's or the dense sets').
fn systems_table(w: &WildSummary) -> String {
    let mut out = String::new();
    out.push_str(
        "| system | markers | found | rough | wrong ids | FP/MP | translation median / p95 (mm) | translation median / p95 (% of distance) | rotation median / p95 (deg) | flipped | jitter px / mm / deg (scenes) | time median / p95 / max (ms) | min. size (px) | corners within 2 sigma (observed / estimated) | corner error median / p95 (px): observed; estimated |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in &w.systems {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {:.1} / {:.1} | {:.2}% / {:.2}% | {:.2} / {:.2} | {} | {} / {} / {} ({}) | {} | {} | {} | {} |",
            display(&r.system),
            r.markers,
            pct(r.detection_rate),
            pct(r.rough_rate),
            r.wrong_ids,
            fp_cell(r),
            r.translation_mm.median,
            r.translation_mm.p95,
            r.translation_pct.median,
            r.translation_pct.p95,
            r.rotation_deg.median,
            r.rotation_deg.p95,
            pct(r.flipped_rate),
            num(r.jitter_corner_px, 3),
            num(r.jitter_translation_mm, 2),
            num(r.jitter_rotation_deg, 3),
            r.jitter_groups,
            time_cell(&r.time_ms),
            r.min_detectable_side_px
                .map_or(format!("no bin >= {:.0}%", 100.0 * MIN_DETECTABLE_RATE), |(lo, hi)| {
                    format!("{lo:.0}-{hi:.0}")
                }),
            sigma_cell(r.corner_sigma.as_ref()),
            corner_error_cell(r)
        );
    }
    out
}

/// Writes the wild section's figures and CSVs into `dir` and returns its
/// Markdown.
pub fn write_wild_section(w: &WildSummary, dir: &Path) -> Result<String> {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\n## In the wild: sampled scenes\n\n\
         Scenes sampled over wide ranges of pose, size, occluders, background, lighting and camera effects \
         (`datasets/wild/`; datasets: {}), the same scenes for every system at equal marker-square size. \
         **Found** = correct + rough: a marker is *correct* when the id is right and every corner lies within \
         3 px or 5% of the side (the larger), *rough* when the id is right but some corner is farther (a robot \
         would trust it). Pose comes from each system's reported corners, undistorted, through one solver \
         (IPPE, the known marker-square side); a pose is *flipped* when its rotation is more than {FLIP_ROTATION_DEG:.0} deg \
         off, or when IPPE's other solution is closer to the truth while the two are at least {FLIP_SEPARATION_DEG:.0} deg apart. \
         Jitter is the median, over scenes rendered several times with fresh sensor noise (at least \
         {JITTER_MIN_RENDERS} renders found), of the spread of the corners (px, RMS over the four), of the \
         translation (mm) and of the rotation (deg). False positives per megapixel are counted on tag-free \
         images. Minimum size: on the markers in plain view (no occluder, no glare spot on the marker, sharp: \
         defocus under {SHARP_DEFOCUS_PX} px and motion under {SHARP_MOTION_PX} px), the smallest bin of the \
         marker's side in pixels from which every bin (of at least {MIN_DETECTABLE_MARKERS} of the system's \
         markers) has at least {:.0}% found; over all markers each bin mixes in occluders, glare and blur up \
         to the drawn maxima, which have their own rows and curves below. \
         Every system runs with its library's default settings, as in the sets above (a new user's first \
         run; the defaults of CopperTag and AprilTag 3 halve the image before the quad search; \
         CopperTag then looks again at full resolution around disc rims too small to read at half \
         size).\n",
        if w.datasets.is_empty() {
            "none".into()
        } else {
            w.datasets.join(", ")
        },
        100.0 * MIN_DETECTABLE_RATE
    );
    out.push_str(&systems_table(w));
    let _ = writeln!(
        out,
        "\nCorners within {SIGMA_MULTIPLE:.0} sigma: of the corners of found markers (correct or rough) whose detection \
         reports a one-sigma corner uncertainty, the share lying within {SIGMA_MULTIPLE:.0} sigma of the true corner, then for \
         the corners the detector observed and those it estimated; \"-\" where a system reports no uncertainty (the \
         issue asks CopperTag for at least 90%).{}\n\n\
         Corner error: the distance of each corner of the found markers to the true corner, median and 95th \
         percentile, over the corners the system reports as observed, then over those it reports as estimated \
         (hidden corners placed from the rest of the marker; \"-\" for a system that flags none; the issue asks \
         CopperTag's estimated corners for a p95 of at most 1.5 px).",
        sigma_sentence(w)
    );
    if !w.scenarios.is_empty() {
        let systems: Vec<String> = w.systems.iter().map(|r| r.system.clone()).collect();
        out.push_str(
            "\n### The detector issue's scenarios\n\n\
             Share found, with the markers counted and the rough detections among those found, on the \
             scenarios the detector issue sets its bars on (the bar is what it asks of CopperTag), then the \
             first row's markers split four ways, in this order: a glare spot on the marker; else heavy blur; \
             else an occluder; else none of these; last, the markers with no occluder and no glare spot, of \
             the bars' sizes, split by size and blur (sharp, heavy as above, moderate between). Coverage is \
             the occluded share of the marker square. For CopperTag, \"at the true corners\" is the share \
             its decoder reads when handed each marker's true corners (`decode_quad`, the library's \
             decoding from four corners): what a perfect quad search would reach with this decoder. A miss \
             under that line was lost in the geometry (no quad near the marker, or one the detector did \
             not trust), one over it in the cells (blur, glare or an occluder left too little to read; \
             the detector, which aligns the print to the image, reads some of those).\n\n",
        );
        out.push_str(&scenarios_table(&w.scenarios, &systems, display));
    }
    out.push_str(
        "\nPer-system figures in `wild-systems.csv`, scenarios in `wild-scenarios.csv`, factor bins in \
         `wild-factors.csv`.\n\n",
    );
    for c in &w.factors {
        if c.bins.is_some() {
            curve_figure(c, dir, &mut out)?;
        } else {
            category_table(c, &mut out);
        }
    }
    if let Some(d) = &w.dense {
        dense_section(d, &mut out);
    }
    for (name, text) in w.csv_files() {
        write_atomic_in_new_dir(&dir.join(name), text.as_bytes())?;
    }
    Ok(out)
}

/// The dense sets' subsection (the field report's dense frames): their
/// own system table and scenario rows (their CSVs are written with the
/// wild set's, [`WildSummary::csv_files`]).
fn dense_section(d: &WildSummary, out: &mut String) {
    let _ = writeln!(
        out,
        "\n### Dense frames\n\n\
         The field report's dense frames, \"ten tags of both families, 60-170 px, tilted, some occluded\", \
         drawn as it describes them (datasets: {}; the dense specs in `datasets/wild/` give the camera, the \
         markers per frame, their sizes and families, each with its reason), with the wild set's \
         backgrounds, light, occluders and JPEG and its blurs on the sensor (so larger in this camera's \
         smaller pixels). Summarised apart from the wild set above, whose scenes they are not: the same \
         columns and scenarios, over these frames only; no tag-free frames (FP/MP \"-\"), no repeats (no \
         jitter). Times are per frame of the dense specs' camera. The scenario rows' blur classes \
         keep the wild set's thresholds in pixels (heavy: defocus >= {HEAVY_DEFOCUS_PX} px or motion >= \
         {HEAVY_MOTION_PX} px), which here are the lower part of wider drawn ranges (the dense specs give \
         them).\n",
        d.datasets.join(", ")
    );
    out.push_str(&systems_table(d));
    if let Some(c) = d.factors.iter().find(|c| c.factor == FAMILY) {
        let shares: Vec<String> = c
            .points
            .iter()
            .map(|p| {
                format!(
                    "{} {} {} of {}",
                    display(&p.system),
                    p.label,
                    pct(p.rate()),
                    p.markers
                )
            })
            .collect();
        let _ = writeln!(
            out,
            "\nBy family (every marker, where a system's frames mix families): {}.",
            shares.join(", ")
        );
    }
    if !d.scenarios.is_empty() {
        let systems: Vec<String> = d.systems.iter().map(|r| r.system.clone()).collect();
        out.push_str("\nThe detector issue's scenarios on the dense frames (as above):\n\n");
        out.push_str(&scenarios_table(&d.scenarios, &systems, display));
    }
    out.push_str(
        "\nPer-system figures in `dense-systems.csv`, scenarios in `dense-scenarios.csv`, factor bins in \
         `dense-factors.csv`.\n\n",
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::Stats;

    #[test]
    fn an_untimed_system_shows_a_dash_for_its_times() {
        assert_eq!(
            time_cell(&Stats::of(&[1.0, 2.0, 4.0])),
            "2.00 / 4.00 / 4.00"
        );
        assert_eq!(time_cell(&Stats::of(&[])), "-");
    }

    /// The dense frames get their own subsection, with the family split
    /// where the frames mix families, and their own CSVs.
    #[test]
    fn the_dense_frames_have_their_subsection_and_family_split() {
        let point = |label: &str, bin, markers, correct| crate::wild_summary::CurvePoint {
            system: "coppertag".into(),
            bin,
            label: label.into(),
            centre: None,
            markers,
            correct,
            rough: 0,
        };
        let dense = WildSummary {
            datasets: vec!["coppertag-dense".into()],
            factors: vec![FactorCurve {
                factor: FAMILY.into(),
                bins: None,
                points: vec![point("ct14", 0, 10, 8), point("ct8", 1, 4, 1)],
            }],
            ..WildSummary::default()
        };
        let w = WildSummary {
            dense: Some(Box::new(dense)),
            ..WildSummary::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let md = write_wild_section(&w, dir.path()).unwrap();
        assert!(md.contains("### Dense frames"), "{md}");
        assert!(md.contains("datasets: coppertag-dense;"), "{md}");
        assert!(
            md.contains("CopperTag ct14 80.0% of 10, CopperTag ct8 25.0% of 4"),
            "{md}"
        );
        for f in [
            "dense-systems.csv",
            "dense-factors.csv",
            "dense-scenarios.csv",
        ] {
            assert!(dir.path().join(f).exists(), "{f}");
        }
        // Without dense frames, no subsection and no dense CSVs.
        let dir = tempfile::tempdir().unwrap();
        let md = write_wild_section(&WildSummary::default(), dir.path()).unwrap();
        assert!(!md.contains("Dense frames"));
        assert!(!dir.path().join("dense-systems.csv").exists());
    }
}
