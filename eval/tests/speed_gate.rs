//! The speed half of the regression gate on a saved, real measurement
//! (`coppertag speed` on the QUICK sets, ci profile, this 2-core machine
//! while two compilers ran beside it): the run passes against a baseline
//! made from itself, and the same frames with our times scaled the way a
//! real slowdown would scale them fail once the slowdown exceeds the
//! tolerance, while smaller drifts do not.

use coppertag_eval::gate::{baseline_of, check_speed, Tolerances};
use coppertag_eval::speed::{confirm_failures, estimate, SpeedReport};

mod common;

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
    assert!(check_speed(&baseline, &blip, tol).iter().all(|v| !v.failed));
    // The first measurement is kept in the report, as measured.
    let slow = slowed(&run, 1.4);
    assert_eq!(blip.first_attempts["stag"], slow.peers["stag"]);

    // A real slowdown fails the second measurement as well.
    let mut real = slowed(&run, 1.4);
    confirm_failures(&mut real, &baseline, tol, |peer| {
        Ok(slow.peers[peer].clone())
    })
    .unwrap();
    let verdicts = check_speed(&baseline, &real, tol);
    assert!(verdicts.iter().all(|v| v.failed), "{verdicts:?}");

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
