//! The road's layout: stopped cars placed from the track seed.

use rand::RngExt;
use red_core::{Seeder, Stream};
use serde::{Deserialize, Serialize};

use crate::config::{DriveConfig, NUM_LANES};

/// A stopped car on the road.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Obstacle {
    /// Position of its centre along the road.
    pub x: f64,
    /// Its lane, `0..3` (0 = rightmost).
    pub lane: usize,
    /// Lateral position of its centre (the lane's centre).
    pub y: f64,
}

/// The layout of one road: obstacles sorted by `x`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Track {
    /// The obstacles, in order along the road.
    pub obstacles: Vec<Obstacle>,
}

impl Track {
    /// The layout for `config.track_seed`: the first obstacle at
    /// `first_obstacle_distance`, each next one `obstacle_spacing_min +
    /// U(0, obstacle_spacing_jitter)` further, up to `road_length -
    /// end_clearance`; each in a uniformly random lane. Only one obstacle
    /// stands at any point along the road, so two lanes are always free.
    pub fn generate(config: &DriveConfig) -> Self {
        let mut rng = Seeder::new(config.track_seed).rng(Stream::Env);
        let mut obstacles = Vec::new();
        let last = config.road_length - config.end_clearance;
        let mut x = config.first_obstacle_distance;
        while x <= last {
            let lane = rng.random_range(0..NUM_LANES);
            obstacles.push(Obstacle {
                x,
                lane,
                y: config.lane_center(lane),
            });
            let jitter = if config.obstacle_spacing_jitter > 0.0 {
                rng.random_range(0.0..config.obstacle_spacing_jitter)
            } else {
                0.0
            };
            x += config.obstacle_spacing_min + jitter;
        }
        Self { obstacles }
    }

    /// The obstacles whose centres lie in `[x_lo, x_hi]`.
    pub fn between(&self, x_lo: f64, x_hi: f64) -> &[Obstacle] {
        let lo = self.obstacles.partition_point(|o| o.x < x_lo);
        let hi = self.obstacles.partition_point(|o| o.x <= x_hi);
        &self.obstacles[lo..hi.max(lo)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_is_seeded_sorted_and_spaced() {
        let c = DriveConfig::default();
        let t = Track::generate(&c);
        assert_eq!(t, Track::generate(&c));
        let other = Track::generate(&DriveConfig {
            track_seed: 1,
            ..c.clone()
        });
        assert_ne!(t, other);
        assert!(t.obstacles.len() >= 8, "{}", t.obstacles.len());
        assert_eq!(t.obstacles[0].x, c.first_obstacle_distance);
        for w in t.obstacles.windows(2) {
            let gap = w[1].x - w[0].x;
            assert!(gap >= c.obstacle_spacing_min);
            assert!(gap < c.obstacle_spacing_min + c.obstacle_spacing_jitter);
        }
        let last = t.obstacles.last().unwrap();
        assert!(last.x <= c.road_length - c.end_clearance);
        let lanes: std::collections::HashSet<usize> = t.obstacles.iter().map(|o| o.lane).collect();
        assert_eq!(lanes.len(), NUM_LANES);
    }

    #[test]
    fn between_selects_by_position() {
        let t = Track::generate(&DriveConfig::default());
        let sel = t.between(100.0, 400.0);
        assert!(sel.iter().all(|o| o.x >= 100.0 && o.x <= 400.0));
        let count = t
            .obstacles
            .iter()
            .filter(|o| o.x >= 100.0 && o.x <= 400.0)
            .count();
        assert_eq!(sel.len(), count);
        assert!(t.between(5000.0, 6000.0).is_empty());
    }
}
