//! The wild benchmark's markers grouped into the scenarios the detector
//! issue sets its bars on, and the main one split by what makes a marker
//! hard, so that a bar's figure comes from `coppertag reproduce` (or
//! `coppertag eval --wild`), not from a script beside it.
//!
//! Every scenario is a filter on a marker's drawn factors (`draws.csv`,
//! merged with its measured side [`SIDE_FACTOR`]); the share found is
//! counted over the same markers as the systems table (first renders of
//! jitter groups only). The ranges are the issue's, chosen from the
//! reference's claims and the field reports, not from what any detector
//! passes; the reason is written beside each.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use crate::draws::{left_off, Factors};
use crate::wild::{MarkerOutcome, Status, SIDE_FACTOR};

/// Smallest marker square (px) of the issue's bars: the size its small-tag
/// item asks ct14 to be read down to (ct8's is 20 px).
pub const BAR_MIN_SIDE_PX: f64 = 24.0;

/// Occluded share of the square up to which the main bar counts a marker:
/// the reference README's claim ("30%").
pub const BAR_MAX_COVERAGE: f64 = 0.30;

/// Upper end of the heavy-occlusion bar: the field report's "30-40%
/// coverage" (the wild set draws up to 40%).
pub const HEAVY_MAX_COVERAGE: f64 = 0.40;

/// Highest JPEG quality of the field report's compressed frames ("JPEG at
/// quality 25-60"): the row of the main bar's markers in frames
/// compressed at most this well (a quality of 0 is a frame with no JPEG
/// step, and is not in it: [`crate::draws::left_off`]).
pub const FIELD_JPEG_MAX_QUALITY: f64 = 60.0;

/// Defocus (Gaussian sigma, px) from which a marker counts as heavily
/// blurred: the upper 40% of the wild set's drawn range (0-2 px).
pub const HEAVY_DEFOCUS_PX: f64 = 1.2;

/// Motion blur (px) from which a marker counts as heavily blurred: the
/// upper 40% of the wild set's drawn range (0-6 px).
pub const HEAVY_MOTION_PX: f64 = 3.6;

/// Why [`heavy_blur`]'s bounds: the reason shown beside both the first
/// row's heavy-blur part and the size-and-blur rows' heavy column.
const HEAVY_BLUR_WHY: &str =
    "defocus >= 1.2 px or motion >= 3.6 px: the upper 40% of the drawn ranges";

/// Defocus (px) under which, with motion under [`SHARP_MOTION_PX`], a
/// marker counts as sharp in the size-and-blur rows: the lower 20% of the
/// wild set's drawn range (0-2 px), a spread well under a pixel.
pub const SHARP_DEFOCUS_PX: f64 = 0.4;

/// Motion blur (px) under which a marker counts as sharp: the lower 20% of
/// the drawn range (0-6 px), about a pixel of smear.
pub const SHARP_MOTION_PX: f64 = 1.2;

/// Marker-square sides (px) bounding the size-and-blur rows' size bins:
/// from the bars' smallest square (the paper's 48 px whole tag, a ct14
/// cell of 1.5 px) through 2 and 2.5 px cells to the set's largest.
pub const SIZE_BINS_PX: [f64; 3] = [BAR_MIN_SIDE_PX, 32.0, 40.0];

/// One scenario: a name, why it is there, the bar the issue sets on it
/// (share found; `None` for the breakdown rows) and which markers it
/// holds.
struct Scenario {
    name: String,
    why: String,
    bar: Option<f64>,
    holds: Box<dyn Fn(&MarkerOutcome) -> bool>,
}

impl Scenario {
    fn new(
        name: &str,
        why: &str,
        bar: Option<f64>,
        holds: impl Fn(&MarkerOutcome) -> bool + 'static,
    ) -> Self {
        Self {
            name: name.into(),
            why: why.into(),
            bar,
            holds: Box::new(holds),
        }
    }
}

fn num(f: &Factors, k: &str) -> Option<f64> {
    f.get(k)?.as_num()
}

fn side_ok(f: &Factors) -> bool {
    num(f, SIDE_FACTOR).is_some_and(|s| s >= BAR_MIN_SIDE_PX)
}

fn coverage(f: &Factors) -> f64 {
    num(f, "occluder_coverage").unwrap_or(0.0)
}

fn main_bar(o: &MarkerOutcome) -> bool {
    side_ok(&o.factors) && coverage(&o.factors) <= BAR_MAX_COVERAGE
}

/// Whether the frame's glare spot lies on marker `o`: glare is drawn on
/// one marker of a frame (`glare_marker`) when its peak is above zero.
fn glared(o: &MarkerOutcome) -> bool {
    num(&o.factors, "glare_peak").is_some_and(|p| p > 0.0)
        && num(&o.factors, "glare_marker").is_some_and(|m| m == o.marker_index as f64)
}

fn heavy_blur(f: &Factors) -> bool {
    num(f, "defocus_px").is_some_and(|d| d >= HEAVY_DEFOCUS_PX) || heavy_motion(f)
}

/// Whether the frame was drawn with a heavy motion blur
/// ([`HEAVY_MOTION_PX`] or more).
pub(crate) fn heavy_motion(f: &Factors) -> bool {
    num(f, "motion_blur_px").is_some_and(|m| m >= HEAVY_MOTION_PX)
}

/// Whether marker `o` is in plain view: no occluder, no glare spot on it,
/// sharp (defocus under [`SHARP_DEFOCUS_PX`] and motion under
/// [`SHARP_MOTION_PX`]), whatever its size. The size-and-blur rows' sharp
/// markers, at every size; the minimum detectable size is measured on
/// them (`wild_summary`).
pub(crate) fn plain(o: &MarkerOutcome) -> bool {
    coverage(&o.factors) == 0.0 && !glared(o) && blur_of(&o.factors) == Blur::Sharp
}

/// The four disjoint groups the main bar's markers are split into, tried
/// in this order.
#[derive(Clone, Copy, PartialEq)]
enum Group {
    Glared,
    HeavyBlur,
    Occluded,
    Clean,
}

fn group_of(o: &MarkerOutcome) -> Group {
    if glared(o) {
        Group::Glared
    } else if heavy_blur(&o.factors) {
        Group::HeavyBlur
    } else if coverage(&o.factors) > 0.0 {
        Group::Occluded
    } else {
        Group::Clean
    }
}

/// The scenarios, bars first, then the main bar's markers by [`Group`].
fn scenarios() -> Vec<Scenario> {
    let mut all = vec![
        Scenario::new(
            "coverage <= 30%, side >= 24 px",
            "the reference README's 30%; 24 px, the issue's smallest ct14 square",
            Some(0.98),
            main_bar,
        ),
        Scenario::new(
            "coverage 30-40%, side >= 24 px",
            "the field report's \"30-40% coverage\"",
            Some(0.90),
            |o| {
                let c = coverage(&o.factors);
                side_ok(&o.factors) && c > BAR_MAX_COVERAGE && c <= HEAVY_MAX_COVERAGE
            },
        ),
        Scenario::new(
            "sticks and cables, side >= 24 px",
            "the field report: sticks and cables across the tag, any coverage drawn (2-40%)",
            Some(0.98),
            |o| {
                let kind = o.factors.get("occluder_kind").and_then(|v| v.as_text());
                side_ok(&o.factors) && matches!(kind, Some("stick" | "cable"))
            },
        ),
        Scenario::new(
            "frames of 2+ markers, coverage <= 30%, side >= 24 px",
            "the field report's dense frames",
            Some(0.98),
            |o| main_bar(o) && num(&o.factors, "markers_per_frame").is_some_and(|n| n >= 2.0),
        ),
        Scenario::new(
            "first row, JPEG quality 60 or lower",
            "the field report's \"JPEG at quality 25-60\"",
            None,
            |o| {
                main_bar(o)
                    && o.factors.get("jpeg_quality").is_some_and(|v| {
                        !left_off("jpeg_quality", v)
                            && v.as_num().is_some_and(|q| q <= FIELD_JPEG_MAX_QUALITY)
                    })
            },
        ),
        Scenario::new(
            "first row: glared",
            "a saturated glare spot on the marker",
            None,
            |o| main_bar(o) && group_of(o) == Group::Glared,
        ),
        Scenario::new(
            "first row: heavy blur, not glared",
            HEAVY_BLUR_WHY,
            None,
            |o| main_bar(o) && group_of(o) == Group::HeavyBlur,
        ),
        Scenario::new(
            "first row: occluded, not glared or heavily blurred",
            "an occluder on 2-30% of the square",
            None,
            |o| main_bar(o) && group_of(o) == Group::Occluded,
        ),
        Scenario::new(
            "first row: none of these",
            "no occluder, no glare, at most moderate blur",
            None,
            |o| main_bar(o) && group_of(o) == Group::Clean,
        ),
    ];
    all.extend(size_and_blur());
    all
}

/// How blurred a marker is, for the size-and-blur rows.
#[derive(Clone, Copy, PartialEq)]
enum Blur {
    Sharp,
    Moderate,
    Heavy,
}

fn blur_of(f: &Factors) -> Blur {
    let d = num(f, "defocus_px").unwrap_or(0.0);
    let m = num(f, "motion_blur_px").unwrap_or(0.0);
    if heavy_blur(f) {
        Blur::Heavy
    } else if d < SHARP_DEFOCUS_PX && m < SHARP_MOTION_PX {
        Blur::Sharp
    } else {
        Blur::Moderate
    }
}

/// Unoccluded, unglared markers of the bars' sizes, split by size
/// ([`SIZE_BINS_PX`]) and blur: where a system's losses lie once
/// occluders and glare are set aside, the two things a user can plan
/// (print size, exposure and focus).
fn size_and_blur() -> Vec<Scenario> {
    let blurs = [
        (
            Blur::Sharp,
            "sharp",
            "defocus < 0.4 px and motion < 1.2 px: the lower 20% of the drawn ranges",
        ),
        (Blur::Moderate, "moderate blur", "between sharp and heavy"),
        (Blur::Heavy, "heavy blur", HEAVY_BLUR_WHY),
    ];
    let mut rows = Vec::new();
    for (k, &lo) in SIZE_BINS_PX.iter().enumerate() {
        let hi = SIZE_BINS_PX.get(k + 1).copied();
        let size = match hi {
            Some(hi) => format!("side {lo:.0}-{hi:.0} px"),
            None => format!("side >= {lo:.0} px"),
        };
        for (blur, label, why) in blurs {
            rows.push(Scenario::new(
                &format!("unoccluded, not glared, {size}: {label}"),
                why,
                None,
                move |o| {
                    let f = &o.factors;
                    let side = num(f, SIDE_FACTOR).unwrap_or(0.0);
                    side >= lo
                        && hi.is_none_or(|hi| side < hi)
                        && coverage(f) == 0.0
                        && !glared(o)
                        && blur_of(f) == blur
                },
            ));
        }
    }
    rows
}

/// One system on one scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScenarioRow {
    /// Scenario, as the report names it.
    pub scenario: String,
    /// Why its range was chosen.
    pub why: String,
    /// The share found the issue asks of CopperTag, if it sets one.
    pub bar: Option<f64>,
    /// Detector.
    pub system: String,
    /// Markers in the scenario.
    pub markers: usize,
    /// Found (correct or rough).
    pub found: usize,
    /// Of those, rough.
    pub rough: usize,
    /// Markers CopperTag's decoder reads at their true corners
    /// ([`crate::wild::read_at_truth`]), when every marker of the row was
    /// tried so (CopperTag's rows).
    #[serde(default)]
    pub read_at_truth: Option<usize>,
}

impl ScenarioRow {
    /// Share found (0 without markers).
    pub fn rate(&self) -> f64 {
        if self.markers == 0 {
            0.0
        } else {
            self.found as f64 / self.markers as f64
        }
    }

    /// Share read at the true corners, where known (0 without markers).
    pub fn read_at_truth_rate(&self) -> Option<f64> {
        self.read_at_truth
            .map(|n| n as f64 / self.markers.max(1) as f64)
    }
}

/// The scenario rows of `systems` (in report order), each over the
/// counted outcomes `outcomes(system)`.
pub fn scenario_rows<'a>(
    systems: &[String],
    outcomes: impl Fn(&str) -> Vec<&'a MarkerOutcome>,
) -> Vec<ScenarioRow> {
    let mut rows = Vec::new();
    for s in scenarios() {
        for sys in systems {
            let mine: Vec<&MarkerOutcome> =
                outcomes(sys).into_iter().filter(|o| (s.holds)(o)).collect();
            if mine.is_empty() {
                continue;
            }
            rows.push(ScenarioRow {
                scenario: s.name.clone(),
                why: s.why.clone(),
                bar: s.bar,
                system: sys.clone(),
                markers: mine.len(),
                found: mine.iter().filter(|o| o.found()).count(),
                rough: mine.iter().filter(|o| o.status == Status::Rough).count(),
                read_at_truth: mine.iter().map(|o| o.read_at_truth.map(usize::from)).sum(),
            });
        }
    }
    rows
}

/// `wild-scenarios.csv`: one row per scenario and system.
pub fn scenarios_csv(rows: &[ScenarioRow]) -> String {
    let mut s = String::from(
        "scenario,why,bar,system,markers,found,rough,found_rate,read_at_truth,read_at_truth_rate\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "\"{}\",\"{}\",{},{},{},{},{},{:.6},{},{}",
            r.scenario.replace('"', "\"\""),
            r.why.replace('"', "\"\""),
            r.bar.map_or(String::new(), |b| format!("{b}")),
            r.system,
            r.markers,
            r.found,
            r.rough,
            r.rate(),
            r.read_at_truth.map_or(String::new(), |n| n.to_string()),
            r.read_at_truth_rate()
                .map_or(String::new(), |v| format!("{v:.6}")),
        );
    }
    s
}

/// The report's table: one line per scenario, one column per system
/// (share found, markers, rough), in the order of `systems`.
pub fn scenarios_table(
    rows: &[ScenarioRow],
    systems: &[String],
    display: impl Fn(&str) -> String,
) -> String {
    let mut out = String::new();
    if rows.is_empty() {
        return out;
    }
    let _ = write!(out, "| scenario (why this range) | bar |");
    for s in systems {
        let _ = write!(out, " {} |", display(s));
    }
    out.push_str("\n|---|---|");
    for _ in systems {
        out.push_str("---|");
    }
    out.push('\n');
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.scenario.as_str()) {
            names.push(&r.scenario);
        }
    }
    for name in names {
        let mine: Vec<&ScenarioRow> = rows.iter().filter(|r| r.scenario == name).collect();
        let first = mine[0];
        let _ = write!(
            out,
            "| {} ({}) | {} |",
            name,
            first.why,
            first
                .bar
                .map_or("-".into(), |b| format!("{:.0}%", 100.0 * b))
        );
        for s in systems {
            match mine.iter().find(|r| &r.system == s) {
                Some(r) => {
                    let _ = write!(
                        out,
                        " {:.1}% of {} ({} rough{}) |",
                        100.0 * r.rate(),
                        r.markers,
                        r.rough,
                        r.read_at_truth_rate().map_or(String::new(), |v| format!(
                            "; {:.1}% at the true corners",
                            100.0 * v
                        ))
                    );
                }
                None => out.push_str(" - |"),
            }
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::draws::FactorValue;

    fn marker(
        marker_index: usize,
        status: Status,
        factors: &[(&str, FactorValue)],
    ) -> MarkerOutcome {
        MarkerOutcome {
            marker_index,
            ..crate::wild_summary::tests::outcome(0, status, factors)
        }
    }

    fn n(v: f64) -> FactorValue {
        FactorValue::Num(v)
    }

    fn t(v: &str) -> FactorValue {
        FactorValue::Text(v.into())
    }

    /// Markers that each land in known scenarios.
    fn markers() -> Vec<MarkerOutcome> {
        vec![
            // 0: clean, found; no JPEG step.
            marker(
                0,
                Status::Correct,
                &[
                    (SIDE_FACTOR, n(30.0)),
                    ("occluder_coverage", n(0.0)),
                    ("jpeg_quality", n(0.0)),
                ],
            ),
            // 1: glared (the frame's glare on marker 1), missed; two markers.
            marker(
                1,
                Status::Missed,
                &[
                    (SIDE_FACTOR, n(40.0)),
                    ("glare_peak", n(1.2)),
                    ("glare_marker", n(1.0)),
                    ("markers_per_frame", n(2.0)),
                ],
            ),
            // 2: glare drawn on marker 1, not this one; heavy defocus; rough.
            marker(
                2,
                Status::Rough,
                &[
                    (SIDE_FACTOR, n(24.0)),
                    ("glare_peak", n(1.2)),
                    ("glare_marker", n(1.0)),
                    ("defocus_px", n(1.5)),
                    ("markers_per_frame", n(2.0)),
                ],
            ),
            // 3: a stick on 20%, found; JPEG quality 61 (over the report's).
            marker(
                0,
                Status::Correct,
                &[
                    (SIDE_FACTOR, n(35.0)),
                    ("occluder_coverage", n(0.2)),
                    ("occluder_kind", t("stick")),
                    ("jpeg_quality", n(61.0)),
                ],
            ),
            // 4: a cable on 35%, missed: heavy occlusion and cables, not the main bar.
            marker(
                0,
                Status::Missed,
                &[
                    (SIDE_FACTOR, n(35.0)),
                    ("occluder_coverage", n(0.35)),
                    ("occluder_kind", t("cable")),
                ],
            ),
            // 5: too small for any bar.
            marker(0, Status::Correct, &[(SIDE_FACTOR, n(20.0))]),
            // 6: glare peak 0 (no glare in the frame) though marker 0 is
            // named; a frame compressed at JPEG quality 60.
            marker(
                0,
                Status::Missed,
                &[
                    (SIDE_FACTOR, n(28.0)),
                    ("glare_peak", n(0.0)),
                    ("glare_marker", n(0.0)),
                    ("jpeg_quality", n(60.0)),
                ],
            ),
        ]
    }

    fn row<'a>(rows: &'a [ScenarioRow], name: &str) -> &'a ScenarioRow {
        rows.iter()
            .find(|r| r.scenario == name)
            .unwrap_or_else(|| panic!("no row {name}"))
    }

    #[test]
    fn markers_fall_into_the_issue_s_scenarios_and_the_breakdown_is_a_partition() {
        let ms = markers();
        let rows = scenario_rows(&["coppertag".into()], |_| ms.iter().collect());
        let main = row(&rows, "coverage <= 30%, side >= 24 px");
        assert_eq!((main.markers, main.found, main.rough), (5, 3, 1));
        assert_eq!(main.bar, Some(0.98));
        let heavy = row(&rows, "coverage 30-40%, side >= 24 px");
        assert_eq!((heavy.markers, heavy.found), (1, 0));
        let sticks = row(&rows, "sticks and cables, side >= 24 px");
        assert_eq!((sticks.markers, sticks.found), (2, 1));
        let multi = row(
            &rows,
            "frames of 2+ markers, coverage <= 30%, side >= 24 px",
        );
        assert_eq!((multi.markers, multi.found, multi.rough), (2, 1, 1));
        // Only marker 6 (quality 60): 0 is no JPEG step, 61 is over.
        let jpeg = row(&rows, "first row, JPEG quality 60 or lower");
        assert_eq!((jpeg.markers, jpeg.found, jpeg.bar), (1, 0, None));
        let glared = row(&rows, "first row: glared");
        assert_eq!((glared.markers, glared.found), (1, 0));
        let blur = row(&rows, "first row: heavy blur, not glared");
        assert_eq!((blur.markers, blur.rough), (1, 1));
        let occluded = row(&rows, "first row: occluded, not glared or heavily blurred");
        assert_eq!((occluded.markers, occluded.found), (1, 1));
        let clean = row(&rows, "first row: none of these");
        assert_eq!((clean.markers, clean.found), (2, 1));
        let parts: usize = [glared, blur, occluded, clean]
            .iter()
            .map(|r| r.markers)
            .sum();
        assert_eq!(parts, main.markers);
        assert!((main.rate() - 0.6).abs() < 1e-12);
    }

    /// The size-and-blur rows split the unoccluded, unglared markers of
    /// the bars' sizes by size bin and blur, each marker into exactly one.
    #[test]
    fn size_and_blur_rows_split_the_plain_markers_by_size_and_blur() {
        let mut ms = markers();
        // 7: a large marker moving 2 px (moderate blur), found.
        ms.push(marker(
            0,
            Status::Correct,
            &[(SIDE_FACTOR, n(45.0)), ("motion_blur_px", n(2.0))],
        ));
        // 8: 32 px exactly belongs to the middle bin; defocus at the sharp
        // bound is moderate.
        ms.push(marker(
            0,
            Status::Missed,
            &[(SIDE_FACTOR, n(32.0)), ("defocus_px", n(SHARP_DEFOCUS_PX))],
        ));
        let rows = scenario_rows(&["coppertag".into()], |_| ms.iter().collect());
        let cell = |name: &str| {
            rows.iter()
                .find(|r| r.scenario == format!("unoccluded, not glared, {name}"))
                .map(|r| (r.markers, r.found, r.rough))
        };
        // Markers 0 and 6 (6's frame has no glare though it names it).
        assert_eq!(cell("side 24-32 px: sharp"), Some((2, 1, 0)));
        // Marker 2: the glare lies on marker 1, not on it.
        assert_eq!(cell("side 24-32 px: heavy blur"), Some((1, 1, 1)));
        assert_eq!(cell("side 32-40 px: moderate blur"), Some((1, 0, 0)));
        assert_eq!(cell("side >= 40 px: moderate blur"), Some((1, 1, 0)));
        assert_eq!(cell("side 24-32 px: moderate blur"), None);
        // Glared (1), occluded (3, 4) and small (5) markers are in none.
        let split: usize = rows
            .iter()
            .filter(|r| r.scenario.starts_with("unoccluded, not glared, "))
            .map(|r| r.markers)
            .sum();
        assert_eq!(split, 5);
    }

    #[test]
    fn the_csv_and_the_table_show_every_scenario_and_system() {
        let ms = markers();
        let systems = vec!["coppertag".to_string(), "stag".to_string()];
        let rows = scenario_rows(&systems, |s| {
            if s == "stag" {
                ms.iter().take(2).collect()
            } else {
                ms.iter().collect()
            }
        });
        let csv = scenarios_csv(&rows);
        assert!(csv.starts_with(
            "scenario,why,bar,system,markers,found,rough,found_rate,read_at_truth,read_at_truth_rate\n"
        ));
        assert!(csv.contains("\"coverage <= 30%, side >= 24 px\",\"the reference README's 30%; 24 px, the issue's smallest ct14 square\",0.98,coppertag,5,3,1,0.600000,,\n"));
        // Quotes inside a reason are doubled.
        assert!(csv.contains("\"the field report's \"\"30-40% coverage\"\"\""));
        let table = scenarios_table(&rows, &systems, |s| s.to_uppercase());
        assert!(table.starts_with(
            "| scenario (why this range) | bar | COPPERTAG | STAG |\n|---|---|---|---|\n"
        ));
        assert!(
            table.contains("| 98% | 60.0% of 5 (1 rough) | 50.0% of 2 (0 rough) |"),
            "{table}"
        );
        // STag's two markers hold no stick: its cell is empty.
        assert!(table.contains("| sticks and cables, side >= 24 px"));
        assert!(
            table
                .lines()
                .any(|l| l.starts_with("| sticks") && l.ends_with(" - |")),
            "{table}"
        );
        assert_eq!(scenarios_table(&[], &systems, |s| s.into()), "");
    }

    /// A row counts the markers read at their true corners when every one
    /// was tried so, and shows their share beside the share found.
    #[test]
    fn a_row_counts_the_markers_read_at_their_true_corners() {
        let mut ms = markers();
        // The main bar's five: read at their true corners but the last.
        let main: Vec<usize> = (0..ms.len()).filter(|&k| main_bar(&ms[k])).collect();
        assert_eq!(main.len(), 5);
        for &k in &main {
            ms[k].read_at_truth = Some(k != main[4]);
        }
        let systems = vec!["coppertag".to_string()];
        let rows = scenario_rows(&systems, |_| ms.iter().collect());
        let main_row = row(&rows, "coverage <= 30%, side >= 24 px");
        assert_eq!(main_row.read_at_truth, Some(4));
        assert_eq!(main_row.read_at_truth_rate(), Some(0.8));
        assert!(scenarios_csv(&rows).contains(",coppertag,5,3,1,0.600000,4,0.800000\n"));
        assert!(scenarios_table(&rows, &systems, |s| s.into())
            .contains("| 60.0% of 5 (1 rough; 80.0% at the true corners) |"));
        // One marker not tried leaves the row without the count.
        ms[main[0]].read_at_truth = None;
        let rows = scenario_rows(&systems, |_| ms.iter().collect());
        assert_eq!(
            row(&rows, "coverage <= 30%, side >= 24 px").read_at_truth,
            None
        );
    }
}
