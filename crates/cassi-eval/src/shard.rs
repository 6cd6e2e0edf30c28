//! Deterministic sharding of a study: scene i (noise seed i, its place in
//! the study's scene list) belongs to shard i mod N, so N processes — on one
//! machine, a Dask or Ray cluster, or a Slurm array — each run their share
//! into a folder of their own, and a merge reads every share back into the
//! study one process would have made.

use std::path::{Path, PathBuf};

/// Shard `index` of `count` (index from 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    index: usize,
    count: usize,
}

impl Shard {
    pub fn new(index: usize, count: usize) -> anyhow::Result<Self> {
        if count == 0 || index >= count {
            anyhow::bail!(
                "shard {index}/{count}: expected K/N with N ≥ 1 and K from 0 to N − 1 \
                 (shard K runs scenes K, K + N, K + 2N, …)"
            );
        }
        Ok(Self { index, count })
    }

    /// `K/N`, as `--shard` takes it.
    pub fn parse(text: &str) -> Result<Self, String> {
        let parsed = text
            .split_once('/')
            .and_then(|(k, n)| Some((k.trim().parse().ok()?, n.trim().parse().ok()?)));
        match parsed {
            Some((k, n)) => Self::new(k, n).map_err(|e| e.to_string()),
            None => Err(format!(
                "'{text}': expected K/N, two whole numbers (e.g. 0/4 … 3/4)"
            )),
        }
    }

    pub fn index(self) -> usize {
        self.index
    }

    pub fn count(self) -> usize {
        self.count
    }

    /// Whether the scene at `scene_index` of the study's list is this
    /// shard's.
    pub fn holds(self, scene_index: usize) -> bool {
        scene_index % self.count == self.index
    }

    /// The shard of `count` that holds the scene at `scene_index`.
    pub fn of_scene(scene_index: usize, count: usize) -> Self {
        Self {
            index: scene_index % count,
            count,
        }
    }

    /// Where this shard of a study into `out` keeps its scene records and
    /// figures: `<out>/shards/<K>-of-<N>/`.
    pub fn folder(self, out: &Path) -> PathBuf {
        out.join("shards")
            .join(format!("{}-of-{}", self.index, self.count))
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_scene_has_exactly_one_shard() {
        for count in 1..6 {
            for i in 0..20 {
                let owners: Vec<_> = (0..count)
                    .filter(|&k| Shard::new(k, count).unwrap().holds(i))
                    .collect();
                assert_eq!(owners, [i % count]);
                assert!(Shard::of_scene(i, count).holds(i));
            }
        }
    }

    #[test]
    fn bad_shards_are_refused_with_the_form_expected() {
        assert_eq!(Shard::parse("2/4").unwrap(), Shard::new(2, 4).unwrap());
        for bad in ["4/4", "1/0", "x/2", "3", "-1/2"] {
            let e = Shard::parse(bad).unwrap_err();
            assert!(e.contains("K/N") || e.contains("N ≥ 1"), "{bad}: {e}");
        }
    }
}
