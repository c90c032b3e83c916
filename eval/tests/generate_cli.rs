//! `coppertag generate` end to end: files it writes decode, bad input exits
//! 2 with a one-line error and leaves no file behind.

use std::path::Path;

use crate::common;
use common::coppertag;

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn png_decodes_from_its_corners() {
    let dir = tempfile::tempdir().unwrap();
    for (family, id) in [("ct14", 42u64), ("ct8", 4097)] {
        let out = dir.path().join(format!("{family}.png"));
        let st = coppertag()
            .args([
                "generate",
                "--family",
                family,
                "--id",
                &id.to_string(),
                "--px",
                "512",
                "-o",
            ])
            .arg(&out)
            .status()
            .unwrap();
        assert!(st.success());
        let img = image::open(&out).unwrap().to_luma8();
        assert_eq!(img.dimensions(), (512, 512));
        // S = 256 px: data square from 128 to 384 in pixel-edge units.
        let c = [
            [127.5, 127.5],
            [127.5, 383.5],
            [383.5, 383.5],
            [383.5, 127.5],
        ];
        let fam = coppertag::Family::by_name(family).unwrap();
        let r = coppertag::decode_quad(&img, fam, &c).expect("generated tag decodes");
        assert_eq!((r.id, r.corrected), (id, 0));
    }
}

#[test]
fn svg_and_sheet_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("tag.svg");
    let st = coppertag()
        .args([
            "generate", "--family", "ct14", "--id", "42", "--size", "100mm", "-o",
        ])
        .arg(&svg)
        .status()
        .unwrap();
    assert!(st.success());
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains(r#"width="100mm""#));
    let sheet = dir.path().join("sheet.svg");
    let out = coppertag()
        .args([
            "generate", "--family", "ct8", "--ids", "0-47", "--size", "50mm", "--sheet", "a4",
            "--json", "-o",
        ])
        .arg(&sheet)
        .output()
        .unwrap();
    assert!(out.status.success());
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["written"].as_array().unwrap().len(), 4);
    assert_eq!(
        files_in(dir.path()),
        vec![
            "sheet-p2.svg",
            "sheet-p3.svg",
            "sheet-p4.svg",
            "sheet.svg",
            "tag.svg"
        ]
    );
}

#[test]
fn bad_input_exits_2_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["--family", "ct99", "--id", "1", "-o", "x.svg"],
            "unknown tag family",
        ),
        (&["--id", "256", "-o", "x.svg"], "out of range"),
        (
            &["--family", "ct8", "--id", "65536", "-o", "x.png"],
            "out of range",
        ),
        (
            &["--id", "1", "--size", "0mm", "-o", "x.svg"],
            "greater than zero",
        ),
        (
            &["--id", "1", "--size", "-5mm", "-o", "x.svg"],
            "greater than zero",
        ),
        (&["--id", "1", "--px", "0", "-o", "x.png"], "--px"),
        (&["--id", "1", "-o", "x.txt"], ".svg or .png"),
        (&["--ids", "0-3", "-o", "x.svg"], "--sheet"),
        (
            &["--ids", "0-3", "--sheet", "a9", "-o", "x.svg"],
            "unknown paper",
        ),
        (&["--id", "1", "-o", "no/such/dir/x.svg"], "cannot write"),
    ];
    for (args, expect) in cases {
        let out = coppertag()
            .current_dir(dir.path())
            .arg("generate")
            .args(*args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert_eq!(
            err.trim().lines().count(),
            1,
            "{args:?}: not one line: {err}"
        );
        assert!(
            files_in(dir.path()).is_empty(),
            "{args:?} left {:?}",
            files_in(dir.path())
        );
    }
    // An unwritable directory: nothing left behind there either.
    let ro = dir.path().join("ro");
    std::fs::create_dir(&ro).unwrap();
    let mut perm = std::fs::metadata(&ro).unwrap().permissions();
    perm.set_readonly(true);
    std::fs::set_permissions(&ro, perm).unwrap();
    // Root ignores directory permissions; only assert when they bite.
    let probe = std::fs::File::create(ro.join("probe"));
    if probe.is_err() {
        let out = coppertag()
            .args(["generate", "--id", "1", "-o"])
            .arg(ro.join("x.svg"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2));
        assert!(files_in(&ro).is_empty());
    } else {
        std::fs::remove_file(ro.join("probe")).unwrap();
    }
}
