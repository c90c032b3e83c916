//! Quick mode renders a tenth of a dataset (`GenerateOptions::every`); a
//! sampled spec with repeats keeps each chosen scene's renders together,
//! so that quick runs still measure jitter.

use coppertag_synth::{generate, DatasetSpec, GenerateOptions};

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

fn load(dir: &std::path::Path, text: &str) -> DatasetSpec {
    let p = dir.join("thin.toml");
    std::fs::write(&p, text).unwrap();
    DatasetSpec::load(&p).unwrap()
}

#[test]
fn thinning_keeps_jitter_groups_whole() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = load(tmp.path(), &spec_text(3));
    assert_eq!(spec.image_count(), 36);
    // Scenes 0, 5 and 10, each with its three renders.
    assert_eq!(spec.thinned_indices(5), [0, 1, 2, 15, 16, 17, 30, 31, 32]);
    assert_eq!(spec.thinned_indices(1), (0..36).collect::<Vec<_>>());
    let out = tmp.path().join("out");
    generate(
        &spec,
        &out,
        &GenerateOptions {
            every: 5,
            force: false,
        },
        &|_, _| {},
    )
    .unwrap();
    let mut names: Vec<String> = std::fs::read_dir(out.join("images"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [0, 1, 2, 15, 16, 17, 30, 31, 32].map(|i| format!("{i:06}.png"))
    );
}

#[test]
fn thinning_without_repeats_takes_every_nth_image() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = load(tmp.path(), &spec_text(1));
    assert_eq!(spec.thinned_indices(5), [0, 5, 10]);
}
