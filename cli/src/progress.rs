//! Progress bars on standard error (indicatif). They draw only when standard
//! error is a terminal, so logs and tests stay clean.

use indicatif::{ProgressBar, ProgressStyle};

/// A bar counting `total` units of work, labelled `label`.
pub fn bar(total: u64, label: &str, unit: &str) -> ProgressBar {
    let template =
        format!("{{prefix:>24}} [{{bar:32}}] {{pos}}/{{len}} {unit} {{elapsed}} (eta {{eta}})");
    let style = ProgressStyle::with_template(&template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    ProgressBar::new(total)
        .with_style(style)
        .with_prefix(label.to_string())
}
