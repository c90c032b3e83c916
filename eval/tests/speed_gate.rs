//! The speed half of the regression gate on a saved, real measurement
//! (`coppertag speed` on the QUICK sets, ci profile, this 2-core machine
//! while two compilers ran beside it): the run passes against a baseline
//! made from itself, and the same frames with our times scaled the way a
//! real slowdown would scale them fail once the slowdown exceeds the
//! tolerance, while smaller drifts do not.

use coppertag_eval::gate::{baseline_of, check_speed, Tolerances};
use coppertag_eval::speed::{estimate, SpeedReport};

fn saved_run() -> SpeedReport {
    let text = include_str!("fixtures/speed-run.json");
    serde_json::from_str(text).expect("the fixture is a speed report")
}

/// The saved run with our times multiplied by `factor`, estimated anew.
fn slowed(run: &SpeedReport, factor: f64) -> SpeedReport {
    let mut out = run.clone();
    for p in out.peers.values_mut() {
        p.ratio = estimate(&p.frames, run.options.resamples, run.options.seed, factor);
    }
    out
}

#[test]
fn the_saved_run_passes_against_itself_with_bands_around_the_median() {
    let run = saved_run();
    assert_eq!(
        run.peers.len(),
        3,
        "apriltag3, aruco3 and stag were measured"
    );
    for (peer, p) in &run.peers {
        assert!(p.frames.len() >= 50, "{peer}: {} frames", p.frames.len());
        assert!(
            p.ratio.low <= p.ratio.median && p.ratio.median <= p.ratio.high,
            "{peer}: {:?}",
            p.ratio
        );
    }
    let baseline = baseline_of(&[], Some(&run), None, "test");
    let verdicts = check_speed(&baseline, &run, Tolerances::default());
    assert_eq!(verdicts.len(), 3);
    assert!(verdicts.iter().all(|v| !v.failed), "{verdicts:?}");
}

#[test]
fn a_forty_percent_slowdown_fails_for_every_peer() {
    let run = saved_run();
    let baseline = baseline_of(&[], Some(&run), None, "test");
    let verdicts = check_speed(&baseline, &slowed(&run, 1.4), Tolerances::default());
    for v in &verdicts {
        assert!(v.failed, "not caught: {v}");
        assert!(v.to_string().contains("FAILED"), "{v}");
    }
}

#[test]
fn a_ten_percent_drift_is_inside_the_tolerance() {
    let run = saved_run();
    let baseline = baseline_of(&[], Some(&run), None, "test");
    let verdicts = check_speed(&baseline, &slowed(&run, 1.1), Tolerances::default());
    assert!(verdicts.iter().all(|v| !v.failed), "{verdicts:?}");
}

#[test]
fn a_peer_missing_from_the_run_fails() {
    let run = saved_run();
    let baseline = baseline_of(&[], Some(&run), None, "test");
    let mut partial = run.clone();
    partial.peers.remove("stag");
    let verdicts = check_speed(&baseline, &partial, Tolerances::default());
    let stag = verdicts.iter().find(|v| v.peer == "stag").unwrap();
    assert!(stag.failed && stag.now.is_none());
    assert!(stag.to_string().contains("not measured"));
}
