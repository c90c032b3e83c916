//! Renders a dataset without the `coppertag` CLI (handy for profiling the
//! library alone):
//!
//!     cargo run --release -p coppertag-synth --example render_dataset -- SPEC OUT_DIR [EVERY]
//!
//! Prints the timing breakdown as one JSON line.

use std::path::PathBuf;

use coppertag_synth::{generate, DatasetSpec, GenerateOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: render_dataset SPEC OUT_DIR [EVERY]");
        std::process::exit(2);
    }
    let spec = DatasetSpec::load(&PathBuf::from(&args[0]))?;
    let every = args.get(2).map_or(Ok(1), |s| s.parse())?;
    let opts = GenerateOptions { every, force: true };
    let r = generate(&spec, &PathBuf::from(&args[1]), &opts, &|_, _| {})?;
    let n = r.images.max(1) as f64;
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1000.0 / n;
    println!(
        "{{\"images\": {}, \"wall_s\": {:.3}, \"images_per_s\": {:.2}, \"threads\": {}, \"ms_per_image\": {{\"render\": {:.2}, \"png_encode\": {:.2}, \"png_write\": {:.2}, \"mcap\": {:.2}, \"csv\": {:.3}}}, \"png_bytes\": {}, \"mcap_bytes\": {}}}",
        r.images,
        r.wall.as_secs_f64(),
        r.images_per_second(),
        rayon::current_num_threads(),
        ms(r.stages.render),
        ms(r.stages.png),
        ms(r.stages.write_png),
        ms(r.stages.mcap),
        ms(r.stages.csv),
        r.png_bytes,
        r.mcap_bytes
    );
    Ok(())
}
