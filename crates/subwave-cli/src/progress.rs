//! Progress bars on stderr for slow library calls (the remesher's stages).

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The remesher's stages and their share of its time.
const STAGES: [(&str, f64); 7] = [
    ("prepare", 0.05),
    ("simplify", 0.3),
    ("parameterize", 0.05),
    ("sampling", 0.2),
    ("resample", 0.1),
    ("relax", 0.25),
    ("quality", 0.05),
];

/// Runs `f` with a progress callback `(stage, fraction)` drawing a bar labelled `label` on
/// stderr, shown only once the work has taken a second (and never when `quiet`).
pub fn with_bar<T>(label: &str, quiet: bool, f: impl FnOnce(&mut dyn FnMut(&str, f64)) -> T) -> T {
    let bar = ProgressBar::with_draw_target(Some(1000), ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{spinner}} {label} {{msg:12}} [{{bar:30}}] {{percent:>3}}% {{elapsed}}"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    let start = Instant::now();
    let mut shown = quiet;
    let result = f(&mut |stage, x| {
        if !shown && start.elapsed() > Duration::from_secs(1) {
            bar.set_draw_target(ProgressDrawTarget::stderr());
            shown = true;
        }
        let i = STAGES.iter().position(|s| s.0 == stage);
        let done = match i {
            Some(i) => {
                STAGES[..i].iter().map(|s| s.1).sum::<f64>() + STAGES[i].1 * x.clamp(0.0, 1.0)
            }
            None => x.clamp(0.0, 1.0),
        };
        bar.set_message(stage.to_string());
        bar.set_position((done * 1000.0) as u64);
    });
    bar.finish_and_clear();
    result
}
