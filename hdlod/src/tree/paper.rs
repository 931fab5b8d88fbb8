//! The paper's table 2 on a tree (Semenov et al. 2020, table 2; DESIGN.md
//! section 5): triangles and clusters of the cut against drawing every
//! present object, at the start, 1/3, 2/3 and end of the period and over an
//! animation, with the camera where the whole scene fills the screen (1/1),
//! 1/4 and 1/16 of it. 1920x1080, fov_y 60 degrees, 1 pixel of error.
//!
//! The camera looks at the centre of the scene's bounding sphere (the
//! manifest's bounds, all periods) from azimuth 45 and elevation 30 degrees.
//! "1/1" is the nearest distance at which the sphere fits the frustum,
//! `R / sin(fov_y / 2)` (the vertical field is the narrower one at 16:9);
//! "1/4" and "1/16" of the screen's area are twice and four times that.
//! The baseline draws every leaf (an original object) present at `t`, with
//! no frustum culling: at these distances the whole scene is in view anyway.

use std::time::Instant;

use glam::DVec3;

use super::cut::cut_into;
use super::{Baseline, CameraSpec, Cut, Tree, View, Viewport};
use crate::scene::Up;

pub const VIEWPORT: Viewport = Viewport {
    width: 1920,
    height: 1080,
};
pub const FOV_Y_DEG: f64 = 60.0;
pub const PIXEL_ERROR: f64 = 1.0;
/// The screens of the table and their distance factors.
pub const SCREENS: [(&str, f64); 3] = [("1/1", 1.0), ("1/4", 2.0), ("1/16", 4.0)];
/// The times of the table as fractions of the period.
pub const TIMES: [(&str, f64); 4] = [
    ("start", 0.0),
    ("1/3", 1.0 / 3.0),
    ("2/3", 2.0 / 3.0),
    ("end", 1.0),
];

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Row {
    /// `start`, `1/3`, `2/3`, `end` or `animation`.
    pub time: String,
    /// `1/1`, `1/4` or `1/16`.
    pub screen: String,
    pub triangles: f64,
    pub clusters: f64,
    pub baseline_triangles: f64,
    pub baseline_draws: f64,
    /// Median cut time (a cell) or mean (the animation), in microseconds.
    pub micros: f64,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Report {
    pub rows: Vec<Row>,
    /// Over every cut timed (cells and animation frames).
    pub median_micros: f64,
    pub p99_micros: f64,
    pub cuts: usize,
}

/// The camera of the table at `factor` times the nearest distance.
pub fn camera(tree: &Tree, factor: f64) -> CameraSpec {
    let centre = (tree.bounds.min + tree.bounds.max) / 2.0;
    let radius = (tree.bounds.diagonal() / 2.0).max(1e-6);
    let (az, el) = (45f64.to_radians(), 30f64.to_radians());
    let (h1, h2, v) = (el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
    let (dir, up) = match tree.up {
        Up::Y => (DVec3::new(h1, v, h2), [0.0, 1.0, 0.0]),
        Up::Z => (DVec3::new(h1, h2, v), [0.0, 0.0, 1.0]),
    };
    let distance = factor * radius / (FOV_Y_DEG.to_radians() / 2.0).sin();
    CameraSpec {
        position: Some((centre + dir * distance).to_array()),
        target: Some(centre.to_array()),
        up: Some(up),
        fov_y_deg: Some(FOV_Y_DEG),
        aspect: Some(f64::from(VIEWPORT.width) / f64::from(VIEWPORT.height)),
        near: Some((distance - radius) * 0.5),
        far: Some(distance + 2.0 * radius),
        view_projection: None,
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// The table: each cell's cut timed `repeats` times (median), and the mean
/// over `frames` animation frames spread evenly across the period.
pub fn table(tree: &Tree, frames: usize, repeats: usize) -> Report {
    let span = tree.time.seconds;
    let baseline = Baseline::of(tree);
    let (mut cut, mut stack) = (Cut::default(), Vec::new());
    let mut all = Vec::new();
    let mut rows = Vec::new();
    let mut timed = |view: &View, t: f64, cut: &mut Cut| {
        let start = Instant::now();
        cut_into(tree, view, t, cut, &mut stack);
        let micros = start.elapsed().as_secs_f64() * 1e6;
        all.push(micros);
        micros
    };
    for (screen, factor) in SCREENS {
        let view = View::new(&camera(tree, factor), VIEWPORT, PIXEL_ERROR, DVec3::Y)
            .expect("the table's camera is valid");
        for (name, fraction) in TIMES {
            let t = span * fraction;
            let mut times: Vec<f64> = (0..repeats.max(1))
                .map(|_| timed(&view, t, &mut cut))
                .collect();
            times.sort_by(f64::total_cmp);
            let base = baseline.present(t);
            rows.push(Row {
                time: name.into(),
                screen: screen.into(),
                triangles: cut.stats.triangles as f64,
                clusters: cut.stats.clusters as f64,
                baseline_triangles: base.triangles as f64,
                baseline_draws: base.draws as f64,
                micros: percentile(&times, 0.5),
            });
        }
        let mut sum = [0.0; 5];
        for i in 0..frames {
            let t = if frames > 1 {
                span * i as f64 / (frames - 1) as f64
            } else {
                0.0
            };
            let micros = timed(&view, t, &mut cut);
            let base = baseline.present(t);
            let values = [
                cut.stats.triangles as f64,
                cut.stats.clusters as f64,
                base.triangles as f64,
                base.draws as f64,
                micros,
            ];
            for (s, v) in sum.iter_mut().zip(values) {
                *s += v;
            }
        }
        let n = frames.max(1) as f64;
        rows.push(Row {
            time: "animation".into(),
            screen: screen.into(),
            triangles: sum[0] / n,
            clusters: sum[1] / n,
            baseline_triangles: sum[2] / n,
            baseline_draws: sum[3] / n,
            micros: sum[4] / n,
        });
    }
    all.sort_by(f64::total_cmp);
    Report {
        rows,
        median_micros: percentile(&all, 0.5),
        p99_micros: percentile(&all, 0.99),
        cuts: all.len(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::sample::write_sample_tree;

    #[test]
    fn table_of_the_sample_tree() {
        let dir = tempfile::tempdir().unwrap();
        let tree = write_sample_tree(&dir.path().join("t"), 5, 6).unwrap();
        let report = table(&tree, 30, 3);
        assert_eq!(report.rows.len(), 15);
        assert_eq!(report.cuts, 3 * (4 * 3 + 30));
        for row in &report.rows {
            assert!(row.triangles <= row.baseline_triangles, "{row:?}");
        }
        let cell = |time: &str, screen: &str| {
            report
                .rows
                .iter()
                .find(|r| r.time == time && r.screen == screen)
                .unwrap()
                .clone()
        };
        // Farther away, coarser; the whole scene is in view at 1/1.
        assert!(cell("end", "1/16").triangles < cell("end", "1/1").triangles);
        assert!(cell("end", "1/1").clusters > 0.0);
        // At the start nothing of the tower is installed yet.
        assert!(cell("start", "1/1").baseline_triangles < cell("2/3", "1/1").baseline_triangles);
    }
}
