//! Quick mode renders a tenth of a dataset (`GenerateOptions::every`); of
//! a sampled spec it takes the first scenes (a Halton prefix is spread
//! evenly; every 10th point is not) with all their renders, so that quick
//! runs still measure jitter.

use coppertag_synth::{generate, GenerateOptions};

use crate::common;
use common::{generate_every, load};

fn spec_text(repeats: usize) -> String {
    format!(
        r#"
name = "thin"
seed = 5

[camera]
width = 160
height = 120
fx = 200.0

[sample]
markers = [{{ system = "coppertag", family = "ct14" }}]
count = 12
repeats = {repeats}
square_m = 0.05
side_px = [20, 30]
read_noise_dn = [0.5, 4]
"#
    )
}

#[test]
fn thinning_keeps_jitter_groups_whole() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = load(tmp.path(), "thin.toml", &spec_text(3));
    assert_eq!(spec.image_count(), 36);
    // The first 12 / 5 -> 3 scenes, each with its three renders.
    assert_eq!(spec.thinned_indices(5), (0..9).collect::<Vec<_>>());
    assert_eq!(spec.thinned_indices(1), (0..36).collect::<Vec<_>>());
    let out = tmp.path().join("out");
    generate_every(&spec, &out, 5);
    let mut names: Vec<String> = std::fs::read_dir(out.join("images"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        (0..9).map(|i| format!("{i:06}.png")).collect::<Vec<_>>()
    );
}

#[test]
fn thinning_a_sampled_spec_keeps_the_spread_of_its_factors() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = load(tmp.path(), "thin.toml", &spec_text(1));
    assert_eq!(spec.thinned_indices(5), [0, 1, 2]);
    // Why a prefix: contrast is drawn in Halton base 3, so every 3rd scene
    // keeps to one third of its range; the first tenth spreads over it.
    let text = spec_text(1).replace("count = 12", "count = 30").replace(
        "read_noise_dn = [0.5, 4]",
        "read_noise_dn = [0.5, 4]\ncontrast = [0.45, 0.88]",
    );
    let spec = load(tmp.path(), "thin.toml", &text);
    let out = tmp.path().join("all");
    generate(&spec, &out, &GenerateOptions::default(), &|_, _| {}).unwrap();
    let draws = std::fs::read_to_string(out.join("draws.csv")).unwrap();
    let contrast: Vec<f64> = draws
        .lines()
        .filter(|l| l.contains(",contrast,"))
        .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(contrast.len(), 30);
    let spread = |v: &[f64]| {
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        hi - lo
    };
    let third = (0.88 - 0.45) / 3.0;
    let prefix: Vec<f64> = spec
        .thinned_indices(3)
        .into_iter()
        .map(|i| contrast[i])
        .collect();
    let strided: Vec<f64> = contrast.iter().step_by(3).copied().collect();
    assert_eq!(prefix.len(), strided.len());
    assert!(spread(&strided) <= third + 1e-9, "{strided:?}");
    assert!(spread(&prefix) > third, "{prefix:?}");
}
