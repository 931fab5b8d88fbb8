//! Progress of long commands: bars on a terminal, plain log lines otherwise
//! (CI logs, pipes), so that a build of minutes is never silent.

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

pub struct Report {
    bar: Option<ProgressBar>,
    plain: Mutex<Plain>,
    quiet: bool,
}

struct Plain {
    name: String,
    total: u64,
    done: u64,
    started: Instant,
    last_percent: u64,
}

impl Report {
    /// Bars when stderr is a terminal, log lines otherwise; nothing when
    /// `quiet` (for `--json`, whose stdout must stay clean; stderr still
    /// carries errors).
    pub fn new(quiet: bool) -> Self {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let bar = ProgressBar::new(0);
            bar.set_style(
                ProgressStyle::with_template("{msg:32} [{bar:40}] {pos}/{len} {elapsed}")
                    .expect("the template is valid")
                    .progress_chars("=> "),
            );
            bar
        });
        Report {
            bar,
            plain: Mutex::new(Plain {
                name: String::new(),
                total: 0,
                done: 0,
                started: Instant::now(),
                last_percent: 0,
            }),
            quiet,
        }
    }

    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

impl hdlod::build::Progress for Report {
    fn phase(&self, name: &str, total: u64) {
        if let Some(bar) = &self.bar {
            bar.set_message(name.to_string());
            bar.set_length(total);
            bar.set_position(0);
            return;
        }
        let mut p = self.plain.lock().expect("progress lock");
        *p = Plain {
            name: name.to_string(),
            total,
            done: 0,
            started: Instant::now(),
            last_percent: 0,
        };
        if !self.quiet {
            eprintln!("{name}: {total} to do");
        }
    }

    fn advance(&self, n: u64) {
        if let Some(bar) = &self.bar {
            bar.inc(n);
            return;
        }
        let mut p = self.plain.lock().expect("progress lock");
        p.done += n;
        let percent = (p.done * 100).checked_div(p.total).unwrap_or(100);
        // One line per quarter keeps logs short on big builds.
        if !self.quiet && percent >= p.last_percent + 25 {
            p.last_percent = percent - percent % 25;
            eprintln!(
                "{}: {}% ({}/{}) {:.1}s",
                p.name,
                p.last_percent,
                p.done,
                p.total,
                p.started.elapsed().as_secs_f64()
            );
        }
    }
}
