//! Build configuration and the per-level thresholds of docs/method.md section 3:
//! `w(l) = W 2^(l-L)`, `eps(l) = k_eps w(l)`, `gamma(l) = gamma_max l / L`.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::geometry::ErrorMetric;
use crate::scene::ScheduleOptions;

/// Every knob of the build, with documented defaults. Stored in the tree's
/// manifest so that a tree says how it was made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BuildConfig {
    /// Number of levels `L` above the leaves; `None` picks it so that
    /// `w(1)` is about the median object size (at least 1, at most 24).
    pub levels: Option<u32>,
    /// Spatial error budget of a level as a fraction of its size:
    /// `eps(l) = k_eps w(l)`. With the default 0.035 a cluster is drawn
    /// once it covers about 30 pixels of error budget (docs/benchmarks.md
    /// compares 0.0125 to 0.05 on the paper scene).
    pub k_eps: f64,
    /// Temporal error budget of the top level: `gamma(l) = gamma_max l / L`.
    pub gamma_max: f64,
    /// The most children a cluster may have.
    pub max_children: usize,
    /// The most steps a cluster's fractional visibility keeps (K).
    pub max_steps: usize,
    /// The Hausdorff bound is refined until its gap is below this fraction
    /// of the level's budget.
    pub hausdorff_fraction: f64,
    /// Error budgets of the discrete LOD chain above each dynamic model, as
    /// shares of the model's size (its box diagonal), finest first.
    pub dynamic_budgets: Vec<f64>,
    /// A coarser version (a dynamic chain's step, the single-child parent
    /// of a cluster with no neighbours) is kept only when it has at most
    /// this share of the triangles below it.
    pub min_reduction: f64,
    /// What `eps_c` bounds: `geometry` (the Hausdorff distance, as the
    /// paper) or `appearance` (each point also held to its own colour, so
    /// colour patterns stay until they are under the budget, at about 2.5
    /// times the triangles per cut; docs/benchmarks.md). Either is a bound
    /// of the geometric distance (docs/method.md section 2).
    pub error_metric: ErrorMetric,
    /// Bake the colours a reduced cluster drops into a texture of its own
    /// (`geometry::bake`): a box or quad keeps its part's colour pattern
    /// as texels, not triangles. Colour only: geometry and every `eps`
    /// are the same either way. Off by default: the paper scene's baked
    /// build took 728 s of CPU where a geometric one took 49 s on the same
    /// machine, and a geometry update of a baked tree builds in full
    /// (docs/benchmarks.md, "The colour seen at a slant"; docs/method.md,
    /// "Geometry updates").
    pub bake: bool,
    /// The most texels along either side of a cluster's baked texture; a
    /// cluster whose texels of its error's size would not fit is baked
    /// coarser.
    pub bake_max_texels: u32,
    /// When constructed and demolished objects count as present; `None`
    /// keeps the scene file's own `schedule_options`.
    pub schedule: Option<ScheduleOptions>,
}

impl Default for BuildConfig {
    fn default() -> Self {
        BuildConfig {
            levels: None,
            k_eps: 0.035,
            gamma_max: 0.05,
            max_children: 8,
            max_steps: 32,
            hausdorff_fraction: 0.1,
            dynamic_budgets: vec![0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5],
            min_reduction: 0.8,
            error_metric: ErrorMetric::Geometry,
            bake: false,
            bake_max_texels: 1024,
            schedule: None,
        }
    }
}

impl BuildConfig {
    /// Rejects values the algorithm cannot work with: an
    /// [`Error::Argument`] at the field's name.
    pub fn validate(&self) -> Result<()> {
        let bad = |f: &str, m: &str| Err(Error::argument(f, m));
        if self.levels == Some(0) || self.levels.is_some_and(|l| l > 40) {
            return bad("levels", "must be between 1 and 40");
        }
        if !(self.k_eps.is_finite() && self.k_eps > 0.0) {
            return bad("k_eps", "must be a positive number");
        }
        if !(self.gamma_max.is_finite() && (0.0..=1.0).contains(&self.gamma_max)) {
            return bad("gamma_max", "must be between 0 and 1");
        }
        if self.max_children < 2 {
            return bad("max_children", "must be at least 2");
        }
        if self.max_steps < 2 {
            return bad("max_steps", "must be at least 2");
        }
        if !(self.hausdorff_fraction.is_finite()
            && self.hausdorff_fraction > 0.0
            && self.hausdorff_fraction <= 1.0)
        {
            return bad("hausdorff_fraction", "must be in (0, 1]");
        }
        if let Some(r) = self
            .dynamic_budgets
            .iter()
            .find(|r| !(**r > 0.0 && **r <= 1.0))
        {
            return bad("dynamic_budgets", &format!("budget {r} is not in (0, 1]"));
        }
        if !(self.min_reduction > 0.0 && self.min_reduction <= 1.0) {
            return bad("min_reduction", "must be in (0, 1]");
        }
        if !(16..=8192).contains(&self.bake_max_texels) {
            return bad("bake_max_texels", "must be between 16 and 8192");
        }
        Ok(())
    }
}

/// The thresholds of one level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Thresholds {
    pub level: u32,
    /// Largest merged box diagonal.
    pub w: f64,
    /// Spatial error budget.
    pub eps: f64,
    /// Temporal error budget (fraction of the span).
    pub gamma: f64,
}

/// `L` for a scene of diagonal `scene_w` whose median object size is
/// `median_w`, unless the configuration fixes it.
pub fn level_count(config: &BuildConfig, scene_w: f64, median_w: f64) -> u32 {
    config.levels.unwrap_or_else(|| {
        if median_w <= 0.0 || scene_w <= median_w {
            return 1;
        }
        ((scene_w / median_w).log2().ceil() as u32 + 1).clamp(1, 24)
    })
}

pub fn thresholds(config: &BuildConfig, scene_w: f64, levels: u32, level: u32) -> Thresholds {
    let w = scene_w * 2f64.powi(level as i32 - levels as i32);
    Thresholds {
        level,
        w,
        eps: config.k_eps * w,
        gamma: config.gamma_max * f64::from(level) / f64::from(levels),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_grow_with_the_level() {
        let c = BuildConfig::default();
        assert_eq!(level_count(&c, 512.0, 1.0), 10);
        let top = thresholds(&c, 512.0, 10, 10);
        assert_eq!(top.w, 512.0);
        assert!((top.gamma - c.gamma_max).abs() < 1e-12);
        let first = thresholds(&c, 512.0, 10, 1);
        assert_eq!(first.w, 1.0);
        assert_eq!(first.eps, c.k_eps);
        assert!(c.validate().is_ok());
        let bad = BuildConfig {
            max_children: 1,
            ..c
        };
        assert!(matches!(bad.validate(), Err(Error::Argument { at, .. }) if at == "max_children"));
    }
}
