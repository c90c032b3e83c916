//! The speed half of the regression gate on saved, real measurements
//! (`coppertag speed` on the QUICK sets, ci profile, this 2-core machine):
//! a run passes against a baseline made from itself, and the same frames
//! with our times scaled the way a real slowdown would scale them fail
//! once the slowdown exceeds the tolerance, while smaller drifts, and one
//! peer drifting alone, do not. The second run is the clean clone's CI run
//! of commit 43cabe9 that the per-peer rule failed on unchanged code.

use coppertag_eval::gate::{baseline_of, check_speed, Baseline, Tolerances};
use coppertag_eval::speed::{confirm_failures, estimate, SpeedReport};

use crate::common;

fn saved_run() -> SpeedReport {
    let text = include_str!("fixtures/speed-run.json");
    serde_json::from_str(text).expect("the fixture is a speed report")
}

/// The CI run of 43cabe9 (a clean clone, `make test`; STag was measured
/// twice, both bands above the per-peer limit) and the baseline it was
/// checked against (made the day before on a busy machine).
fn drifted_run() -> (SpeedReport, Baseline) {
    let run = serde_json::from_str(include_str!("fixtures/speed-run-drift.json"))
        .expect("the fixture is a speed report");
    let baseline = serde_json::from_str(include_str!("fixtures/speed-baseline-drift.json"))
        .expect("the fixture is a baseline");
    (run, baseline)
}

/// `run` with our times against `peer` alone multiplied by `factor`: what
/// a change in that peer's own time by `1 / factor` would have measured.
fn one_peer_scaled(run: &SpeedReport, peer: &str, factor: f64) -> SpeedReport {
    let mut out = run.clone();
    let p = out.peers.get_mut(peer).expect("the peer was measured");
    p.ratio = estimate(&p.frames, run.options.resamples, run.options.seed, factor);
    out
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
    let check = check_speed(&baseline, &run, Tolerances::default());
    assert_eq!(check.peers.len(), 3);
    assert!(
        !check.failed && check.peers.iter().all(|v| !v.above),
        "{check:?}"
    );
    // Against itself, the low ends of the bands lie below their medians.
    assert!(check.growth_low < 1.0, "{check:?}");
    assert!(check.to_string().ends_with(": ok"), "{check}");
}

#[test]
fn a_forty_percent_slowdown_fails_for_every_peer() {
    let run = saved_run();
    let baseline = baseline_of(&[], Some(&run), None, "test");
    let check = check_speed(&baseline, &slowed(&run, 1.4), Tolerances::default());
    assert!(check.failed, "not caught: {check}");
    assert!(check.to_string().contains("FAILED"), "{check}");
    for v in &check.peers {
        assert!(v.above, "not above its limit: {v}");
        assert!(v.to_string().contains("band wholly above"), "{v}");
    }
}

#[test]
fn a_ten_percent_drift_is_inside_the_tolerance() {
    let run = saved_run();
    let baseline = baseline_of(&[], Some(&run), None, "test");
    let check = check_speed(&baseline, &slowed(&run, 1.1), Tolerances::default());
    assert!(!check.failed, "{check:?}");
}

#[test]
fn one_peer_drifting_alone_fails_nothing_and_is_not_measured_again() {
    let run = saved_run();
    let baseline = baseline_of(&[], Some(&run), None, "test");
    let tol = Tolerances::default();
    // STag's own time 40% shorter: ours over STag's 1.67x the baseline.
    let mut drift = one_peer_scaled(&run, "stag", 1.0 / 0.6);
    let check = check_speed(&baseline, &drift, tol);
    let stag = check.peers.iter().find(|v| v.peer == "stag").unwrap();
    assert!(stag.above, "{stag}");
    assert!(!check.failed, "{check}");
    let again = confirm_failures(&mut drift, &baseline, tol, |peer| {
        panic!("{peer} was measured again although the check passed")
    })
    .unwrap();
    assert!(again.is_empty() && drift.first_attempts.is_empty());
    // Against two of the three peers, the same growth is ours: it fails.
    let two = one_peer_scaled(&drift, "aruco3", 1.0 / 0.6);
    assert!(check_speed(&baseline, &two, tol).failed);
}

#[test]
fn the_run_that_failed_on_unchanged_code_passes_and_its_slowdown_does_not() {
    let (run, baseline) = drifted_run();
    assert_eq!(run.peers.len(), 4);
    assert_eq!(run.first_attempts.len(), 1, "STag was measured twice");
    let tol = Tolerances::default();
    let check = check_speed(&baseline, &run, tol);
    // STag's band lay wholly above its own limit (0.129x against 0.119x),
    // twice; the others were within theirs.
    for v in &check.peers {
        assert_eq!(v.above, v.peer == "stag", "{v}");
    }
    assert!(!check.failed, "{check}");
    assert!(
        (1.0..1.1).contains(&check.growth_low),
        "median growth {}",
        check.growth_low
    );
    // The same frames with ours 1.4x slower fail.
    let check = check_speed(&baseline, &slowed(&run, 1.4), tol);
    assert!(check.failed, "{check}");
}

#[test]
fn a_peer_missing_from_the_run_fails() {
    let run = saved_run();
    let baseline = baseline_of(&[], Some(&run), None, "test");
    let mut partial = run.clone();
    partial.peers.remove("stag");
    let check = check_speed(&baseline, &partial, Tolerances::default());
    assert!(check.failed, "{check}");
    assert!(check.to_string().contains("not measured: stag"), "{check}");
    let stag = check.peers.iter().find(|v| v.peer == "stag").unwrap();
    assert!(stag.above && stag.now.is_none());
    assert!(stag.to_string().contains("not measured"));
}

#[test]
fn only_failing_peers_are_measured_again_and_the_second_measurement_decides() {
    let run = saved_run();
    let baseline = baseline_of(&[], Some(&run), None, "test");
    let tol = Tolerances::default();

    // Unchanged code: nothing fails, nothing is measured again.
    let mut same = run.clone();
    let again = confirm_failures(&mut same, &baseline, tol, |peer| {
        panic!("{peer} was measured again although it passed")
    })
    .unwrap();
    assert!(again.is_empty() && same.first_attempts.is_empty());

    // A blip: the first measurement is 40% slow, the second is not.
    let mut blip = slowed(&run, 1.4);
    let again = confirm_failures(
        &mut blip,
        &baseline,
        tol,
        |peer| Ok(run.peers[peer].clone()),
    )
    .unwrap();
    assert_eq!(again.len(), 3, "{again:?}");
    assert_eq!(blip.first_attempts.len(), 3);
    assert!(!check_speed(&baseline, &blip, tol).failed);
    // The first measurement is kept in the report, as measured.
    let slow = slowed(&run, 1.4);
    assert_eq!(blip.first_attempts["stag"], slow.peers["stag"]);

    // A real slowdown fails the second measurement as well.
    let mut real = slowed(&run, 1.4);
    confirm_failures(&mut real, &baseline, tol, |peer| {
        Ok(slow.peers[peer].clone())
    })
    .unwrap();
    let check = check_speed(&baseline, &real, tol);
    assert!(
        check.failed && check.peers.iter().all(|v| v.above),
        "{check:?}"
    );

    // A failing re-measurement is an error, not a pass.
    let mut broken = slowed(&run, 1.4);
    let err = confirm_failures(&mut broken, &baseline, tol, |peer| {
        Err(coppertag_eval::EvalError::Detector {
            detector: peer.into(),
            message: "crashed".into(),
        })
    });
    assert!(err.is_err());
}

#[test]
fn a_bad_confirm_baseline_is_a_named_error_before_any_measurement() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("baseline.json");
    std::fs::write(&bad, "{\"entries\": 3}").unwrap();
    for (path, says) in [
        (dir.path().join("missing.json"), "cannot read"),
        (bad, "not a baseline file"),
    ] {
        // No datasets exist under --work: the baseline is refused first.
        let o = common::coppertag()
            .args(["speed", "--quiet", "--work"])
            .arg(dir.path())
            .arg("--confirm-against")
            .arg(&path)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{path:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says), "{path:?}: {err}");
    }
    let o = common::coppertag()
        .args(["speed", "--time-ratio=-0.5", "--work"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--time-ratio must be a non-negative"));
}
