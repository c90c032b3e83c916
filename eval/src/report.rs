//! The paper's tables and figures from evaluated runs.
//!
//! Inputs are [`Summary`] values (from `coppertag eval`); outputs go to one
//! directory: Markdown and CSV tables, SVG and PNG figures, and a README
//! saying what was run. Each table puts the paper's figure beside ours.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use crate::atomic::write_atomic_in_new_dir;
use crate::error::{EvalError, Result};
use crate::metrics::Summary;
use crate::plot::{line_chart, Chart, Series};
use crate::runner;
use crate::wild_summary::WildSummary;

/// Marker systems in the paper's table order, then the fractal markers
/// (not in the paper: the occlusion-designed peer), last so that the
/// paper's four keep their colours in the figures.
pub const SYSTEMS: [&str; 5] = ["aruco3", "apriltag3", "stag", "coppertag", "fractal"];

/// The four simulation sweeps.
pub const SWEEPS: [&str; 4] = ["distance-z", "rotated-x", "rotated-y", "rotated-z"];

fn display(system: &str) -> &'static str {
    match system {
        "aruco3" => "ArUco3",
        "apriltag3" => "AprilTag3",
        "stag" => "STag",
        "fractal" => "Fractal",
        "coppertag" => "CopperTag",
        _ => "other",
    }
}

/// Table I of the paper: detection rate, time (ms), CPU (%), memory (%).
fn paper_table1(system: &str) -> Option<(&'static str, &'static str, &'static str, &'static str)> {
    match system {
        "aruco3" => Some(("100%", "5.44", "14.07", "1.27")),
        "apriltag3" => Some(("100%", "12.23", "13.47", "2.9")),
        "stag" => Some(("94.4%", "23.11", "13.64", "0.93")),
        "coppertag" => Some(("100%", "4.41", "13.24", "2.65")),
        _ => None,
    }
}

/// Table II of the paper: which of the 20 occlusion images (5%..20% x
/// patterns 1..5) each system detected; `None` for a system the paper did
/// not test (the fractal markers).
fn paper_table2(system: &str) -> Option<[bool; 20]> {
    let mut row = [false; 20];
    let set: &[usize] = match system {
        "aruco3" => &[],
        "apriltag3" => &[0, 3],
        "stag" => &[0, 2, 3, 5, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19],
        "coppertag" => &[
            0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19,
        ],
        _ => return None,
    };
    for &i in set {
        row[i] = true;
    }
    Some(row)
}

/// A paper figure in brackets, or `(-)` where the paper has none.
fn paper_mark(paper: Option<bool>) -> &'static str {
    match paper {
        Some(true) => "Y",
        Some(false) => ".",
        None => "-",
    }
}

fn sweep_of(s: &Summary) -> &str {
    s.dataset
        .strip_prefix(&format!("{}-", s.marker))
        .unwrap_or(&s.dataset)
}

fn pct(v: f64) -> String {
    format!("{:.1}%", 100.0 * v)
}

/// Machine facts for the tables' resource columns.
#[derive(Debug, Clone, Copy)]
pub struct Machine {
    /// CPU cores.
    pub cores: usize,
    /// Memory, bytes.
    pub memory: u64,
}

/// A time (ms) with `digits` decimals, or `untimed` (a dash in a table, an
/// empty CSV field) for a run that was not timed ([`runner::timed`]).
fn ms_or(v: Option<f64>, digits: usize, untimed: &str) -> String {
    v.map_or_else(|| untimed.to_string(), |v| format!("{v:.digits$}"))
}

/// Table I: one row per marker system over the four sweeps.
fn table1(summaries: &[Summary], m: Machine, out: &mut String, csv: &mut String) {
    let _ = writeln!(
        out,
        "## Table I: detection rate, speed and resources on the four simulation sweeps\n\n\
         Detection rate over all images of distance-z, rotated-x, rotated-y and rotated-z; time is the mean \
         (and median, 95th percentile and largest) detection time per 1920x1080 image, single-threaded: a \
         real-time loop has to budget for the worst frames, not the typical one. CPU is the detector's CPU time over \
         its wall time, as a share of the whole machine ({} cores here, 8 in the paper) and of one core; memory \
         is the detector process's peak resident memory, as a share of this machine's memory and in MiB. \
         Paper figures in brackets.\n",
        m.cores
    );
    out.push_str("| marker | detection rate | time mean (ms) | time median (ms) | time p95 / max (ms) | CPU % machine | CPU % one core | memory % | memory MiB |\n|---|---|---|---|---|---|---|---|---|\n");
    csv.push_str("marker,images,found,detection_rate,time_mean_ms,time_median_ms,time_p95_ms,time_max_ms,cpu_percent_machine,cpu_percent_core,memory_percent,memory_mib,paper_detection_rate,paper_time_ms,paper_cpu_percent,paper_memory_percent\n");
    for sys in SYSTEMS {
        let rows: Vec<&Summary> = summaries
            .iter()
            .filter(|s| s.marker == sys && SWEEPS.contains(&sweep_of(s)))
            .collect();
        if rows.is_empty() {
            continue;
        }
        let markers: usize = rows.iter().map(|s| s.markers).sum();
        let found: usize = rows.iter().map(|s| s.found).sum();
        // Only the timed runs' times (`runner::timed`).
        let times: Vec<f64> = rows
            .iter()
            .filter(|s| runner::timed(s.sessions))
            .flat_map(|s| s.per_image.iter().filter_map(|p| p.ms))
            .collect();
        let t = crate::metrics::Stats::of(&times);
        let timed = |v: f64| (t.n > 0).then_some(v);
        let ms = |v: f64| ms_or(timed(v), 2, "-");
        let csv_ms = |v: f64| ms_or(timed(v), 4, "");
        let cpu_core = rows.iter().map(|s| s.cpu_percent).sum::<f64>() / rows.len() as f64;
        let mem = rows.iter().map(|s| s.peak_memory_mib).fold(0.0, f64::max);
        let mem_pct = 100.0 * mem * (1u64 << 20) as f64 / m.memory.max(1) as f64;
        let rate = if markers > 0 {
            found as f64 / markers as f64
        } else {
            0.0
        };
        let p = paper_table1(sys).unwrap_or(("-", "-", "-", "-"));
        let _ = writeln!(
            out,
            "| {} | {} ({}) | {} ({}) | {} | {} / {} | {:.2} ({}) | {:.1} | {:.2} ({}) | {:.0} |",
            display(sys),
            pct(rate),
            p.0,
            ms(t.mean),
            p.1,
            ms(t.median),
            ms(t.p95),
            ms(t.max),
            cpu_core / m.cores.max(1) as f64,
            p.2,
            cpu_core,
            mem_pct,
            p.3,
            mem
        );
        let _ = writeln!(
            csv,
            "{sys},{markers},{found},{rate:.6},{},{},{},{},{:.3},{:.3},{mem_pct:.3},{mem:.1},{},{},{},{}",
            csv_ms(t.mean),
            csv_ms(t.median),
            csv_ms(t.p95),
            csv_ms(t.max),
            cpu_core / m.cores.max(1) as f64,
            cpu_core,
            p.0.trim_end_matches('%'),
            p.1,
            p.2,
            p.3
        );
    }
}

/// Table II: the 20 occlusion images.
fn table2(summaries: &[Summary], out: &mut String, csv: &mut String) {
    out.push_str(
        "\n## Table II: the 20 occlusion images\n\n\
         Patterns 1-5 at each coverage level are triangle, same-side, symmetry, diagonal and inner \
         (`datasets/occlusions/paper/`). Each cell: ours, then the paper's in brackets \
         (Y found, . missed, - not in the paper: the fractal markers).\n\n",
    );
    out.push_str("| marker | 5%: 1 2 3 4 5 | 10%: 1 2 3 4 5 | 15%: 1 2 3 4 5 | 20%: 1 2 3 4 5 | found (paper) |\n|---|---|---|---|---|---|\n");
    csv.push_str("marker,pattern,found,paper_found\n");
    for sys in SYSTEMS {
        let Some(s) = summaries
            .iter()
            .find(|s| s.marker == sys && sweep_of(s) == "occlusion")
        else {
            continue;
        };
        let mut images: Vec<_> = s.per_image.iter().collect();
        images.sort_by(|a, b| a.occlusion_pattern.cmp(&b.occlusion_pattern));
        let paper = paper_table2(sys);
        let mut cells = vec![String::new(); 4];
        let mut n_found = 0;
        for (i, img) in images.iter().enumerate().take(20) {
            let found = img.found > 0;
            n_found += usize::from(found);
            let was = paper.map(|p| p[i]);
            let _ = write!(
                cells[i / 5],
                "{}({}) ",
                if found { "Y" } else { "." },
                paper_mark(was)
            );
            let _ = writeln!(
                csv,
                "{sys},{},{},{}",
                img.occlusion_pattern,
                u8::from(found),
                was.map_or(String::new(), |w| u8::from(w).to_string())
            );
        }
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {n_found}/{} ({}) |",
            display(sys),
            cells[0].trim(),
            cells[1].trim(),
            cells[2].trim(),
            cells[3].trim(),
            images.len().min(20),
            paper.map_or("-".into(), |p| format!(
                "{}/20",
                p.iter().filter(|&&w| w).count()
            ))
        );
    }
}

/// Figure 7: mean real-corner error per image against the swept value.
fn figure7(summaries: &[Summary], dir: &Path, out: &mut String) -> Result<()> {
    out.push_str("\n## Figure 7: corner error along the sweeps\n\nMean absolute error of the observed corners in each image, in pixels; gaps are images where the marker was not found.\n\n");
    for sweep in SWEEPS {
        let mut series = Vec::new();
        let mut x_label = "";
        let mut lines = String::new();
        for sys in SYSTEMS {
            let Some(s) = summaries
                .iter()
                .find(|s| s.marker == sys && sweep_of(s) == sweep)
            else {
                continue;
            };
            let points: Vec<(f64, f64)> = s
                .per_image
                .iter()
                .map(|p| {
                    let x = match p.value_deg {
                        Some(d) if p.param != "z" => {
                            x_label = "angle (degrees)";
                            d
                        }
                        _ => {
                            x_label = "distance (m)";
                            p.value
                        }
                    };
                    (x, p.corner_error_px)
                })
                .collect();
            let _ = writeln!(
                lines,
                "| {} | {:.3} | {:.3} | {:.3} | {} |",
                display(sys),
                s.corner_error_real.mean,
                s.corner_error_real.median,
                s.corner_error_real.p95,
                s.corner_error_real.n
            );
            series.push(Series {
                label: display(sys).into(),
                points,
            });
        }
        if series.is_empty() {
            continue;
        }
        let stem = dir.join(format!("fig7-{sweep}"));
        line_chart(
            &stem,
            &Chart {
                title: &format!("Corner error, {sweep}"),
                x_label,
                y_label: "mean corner error (px)",
                y_range: None,
            },
            &series,
        )?;
        let _ = writeln!(
            out,
            "### {sweep}\n\n![{sweep}](fig7-{sweep}.png)\n\n| marker | mean px | median px | p95 px | corners |\n|---|---|---|---|---|\n{lines}"
        );
    }
    Ok(())
}

/// Markers and found markers by coverage bin (percent).
type CoverageBins = BTreeMap<i64, (usize, usize)>;

/// Robustness curves: detection rate against coverage, per scenario, from
/// procedural occlusion datasets (any dataset whose name contains
/// `robust`).
fn robustness(summaries: &[Summary], dir: &Path, out: &mut String, csv: &mut String) -> Result<()> {
    let robust: Vec<&Summary> = summaries
        .iter()
        .filter(|s| s.dataset.contains("robust"))
        .collect();
    if robust.is_empty() {
        return Ok(());
    }
    out.push_str("\n## Robustness to occlusion\n\nDetection rate against the exact fraction of the marker square covered, from procedurally generated occluders, binned by 5% of coverage. The 5-20% column pools the four levels the paper reports.\n\n");
    csv.push_str("marker,scenario,coverage_bin,images,found,rate\n");
    // (scenario) -> (system) -> bin -> (n, found)
    let mut table: BTreeMap<String, BTreeMap<&str, CoverageBins>> = BTreeMap::new();
    for s in &robust {
        for p in &s.per_image {
            let bin = ((p.occlusion_coverage * 100.0) / 5.0).round() as i64 * 5;
            let e = table
                .entry(p.occlusion_scenario.clone())
                .or_default()
                .entry(s.marker.as_str())
                .or_default()
                .entry(bin)
                .or_default();
            e.0 += p.markers;
            e.1 += p.found;
        }
    }
    for (scenario, systems) in &table {
        let mut series = Vec::new();
        let _ = writeln!(out, "### {scenario}\n\n![{scenario}](robustness-{scenario}.png)\n\n| marker | 5-20% | rate by coverage |\n|---|---|---|");
        for sys in SYSTEMS {
            let Some(bins) = systems.get(sys) else {
                continue;
            };
            let mut cells = String::new();
            let mut points = Vec::new();
            let (mut n_low, mut found_low) = (0, 0);
            for (n, found) in bins.range(5..=20).map(|(_, v)| v) {
                n_low += n;
                found_low += found;
            }
            for (bin, (n, found)) in bins {
                let rate = *found as f64 / (*n).max(1) as f64;
                points.push((*bin as f64, 100.0 * rate));
                let _ = write!(cells, "{bin}%: {} (n={n}); ", pct(rate));
                let _ = writeln!(csv, "{sys},{scenario},{bin},{n},{found},{rate:.4}");
            }
            let low = if n_low > 0 {
                format!("{} (n={n_low})", pct(found_low as f64 / n_low as f64))
            } else {
                "-".into()
            };
            let _ = writeln!(
                out,
                "| {} | {low} | {} |",
                display(sys),
                cells.trim_end_matches("; ")
            );
            series.push(Series {
                label: display(sys).into(),
                points,
            });
        }
        out.push('\n');
        line_chart(
            &dir.join(format!("robustness-{scenario}")),
            &Chart {
                title: &format!("Detection rate under occlusion: {scenario}"),
                x_label: "coverage of the marker square (%)",
                y_label: "detection rate (%)",
                y_range: Some((0.0, 102.0)),
            },
            &series,
        )?;
    }
    Ok(())
}

/// The challenge table: any dataset whose name contains `challenge`.
fn challenge(summaries: &[Summary], out: &mut String, csv: &mut String) {
    let rows: Vec<&Summary> = summaries
        .iter()
        .filter(|s| s.dataset.contains("challenge"))
        .collect();
    if rows.is_empty() {
        return;
    }
    out.push_str(
        "\n## Challenge conditions (in the spirit of Table III)\n\n\
         Synthetic defocus and uneven lighting; the paper's physical \"challenge\" set gave CopperTag 48% \
         (not comparable one to one: theirs is real photos).\n\n\
         | dataset | marker | detection rate | median time (ms) |\n|---|---|---|---|\n",
    );
    csv.push_str("dataset,marker,images,found,rate,time_median_ms\n");
    for s in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} |",
            s.dataset,
            display(&s.marker),
            pct(s.detection_rate),
            ms_or(s.median_ms(), 2, "-")
        );
        let _ = writeln!(
            csv,
            "{},{},{},{},{:.4},{}",
            s.dataset,
            s.marker,
            s.markers,
            s.found,
            s.detection_rate,
            ms_or(s.median_ms(), 4, "")
        );
    }
}

/// Every run behind the tables, with its headline figures.
fn runs(summaries: &[Summary], out: &mut String) {
    out.push_str(
        "\n## Every run\n\nOne detector over one dataset each (`build/full/runs/*.mcap` after `make reproduce`; \
         per-image figures in `build/full/results/summary.json`). A dash for the time: the run's \
         detector sessions ran several at once, each on a shard of the images (the robustness sets, \
         which are scored for detection only), so its per-image times are not comparable and are not \
         shown.\n\n\
         | dataset | detector | images | markers | found | wrong ids | false positives | duplicates | median corner px | median ms |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    for s in summaries {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {} |",
            s.dataset,
            s.detector,
            s.images,
            s.markers,
            s.found,
            s.wrong_ids,
            s.false_positives,
            s.duplicates,
            s.corner_error_real.median,
            ms_or(s.median_ms(), 2, "-")
        );
    }
}

/// Writes every table and figure into `dir`; returns the Markdown body.
/// `wild`, when given, adds the sampled-scene section
/// ([`crate::wild_report`]) before the list of runs.
pub fn write_report(
    summaries: &[Summary],
    dir: &Path,
    machine: Machine,
    preamble: &str,
    wild: Option<&WildSummary>,
) -> Result<String> {
    std::fs::create_dir_all(dir).map_err(|e| EvalError::io(dir, e))?;
    let mut md = String::from(preamble);
    let (mut t1, mut t2, mut rb, mut ch) =
        (String::new(), String::new(), String::new(), String::new());
    table1(summaries, machine, &mut md, &mut t1);
    table2(summaries, &mut md, &mut t2);
    figure7(summaries, dir, &mut md)?;
    robustness(summaries, dir, &mut md, &mut rb)?;
    challenge(summaries, &mut md, &mut ch);
    if let Some(w) = wild {
        md.push_str(&crate::wild_report::write_wild_section(w, dir)?);
    }
    runs(summaries, &mut md);
    for (name, body) in [
        ("table1.csv", &t1),
        ("table2.csv", &t2),
        ("robustness.csv", &rb),
        ("challenge.csv", &ch),
    ] {
        if !body.is_empty() {
            write_atomic_in_new_dir(&dir.join(name), body.as_bytes())?;
        }
    }
    Ok(md)
}
