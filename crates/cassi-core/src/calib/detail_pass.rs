//! The scene fit's detail pass: the first pass refitted on a coarse scene
//! that carries the scene's own texture. Its basis is the first pass's with
//! every band multiplied by a detail map d ([`super::coarse_scene`]; one
//! for all bands by default, one per group of bands with
//! [`DetailPass::spectral_groups`]):
//! x_k = d ⊙ (U z)_k. d is the luminance of the proxy reconstruction at the
//! first pass's ψ, smoothed by [`DetailPass::pre_smooth_px`] and divided by
//! its own Gaussian average over [`DetailPass::detail_px`]: ≈ 1 on average,
//! the texture between the nodes in its variation.
//!
//! Why: the first pass's smooth scene leaves textured scenes' detail
//! unexplained, and what it leaves is partly explained by moving ψ. On the
//! aligned cases of the tuning half the fine pass then slid along dx and
//! along dy–α; with the scene-known fit these stay within 0.03 px. The
//! detail gives the texture back to the scene, not to ψ. The luminance is
//! smoothed first because below about a pixel the proxy's detail is the
//! mask's imprint at the ψ it was made with (unsmoothed, the detail map
//! made the fits sharper in probes: σ read low where the pass refitted it).
//! Its scene starts from the first pass's coefficients (d ≈ 1 on average,
//! so they already hold the smooth factor): on the five real snapshots
//! that took the pass from 48–139 scores (3.2–11.9 s) to 36–67 (2.7–5.6
//! s); on the tuning half's four configurations all six within tolerance
//! went 86 → 87 of 180, the wide blur 18 → 16 of 80.
//!
//! [`DetailPass::spectral_groups`] > 1 gives each group of consecutive
//! bands its own map (a texture of colour): on the tuning half's first
//! configuration 3 maps gave 26 of 45 against 25, RMSE mixed
//! (`calibrate_physical_tuning_detail_groups3.json`): not the default.
//!
//! [`DetailSource::GapTv`] takes the maps from GAP-TV's scene instead of
//! the proxy's: on the tuning half's first configuration (45 cases,
//! `calibrate_physical_tuning_detail_gap_tv50.json`, 50 iterations,
//! against the default's answers in `…_tuning_blur_bootstrap_crisp_cells.json`)
//! all six within tolerance stayed 12 of 30 random and 13 of 15 aligned;
//! random RMSE dx 0.155 → 0.146 px, dy 0.040 → 0.035, α 0.063 → 0.060°,
//! aligned dy 0.007 → 0.014 px, α 0.011 → 0.023°, σ unchanged (the pass
//! holds it); the pass took 2.8 s instead of 1.1 (median; runs overlapped,
//! not a timing figure): not the default.
//!
//! Chosen on the tuning half, four configurations
//! (`calibrate_physical_tuning_detail_pass{,_flip_cols,_flip_rows,_transpose}.json`
//! as commit 8daad63 made them, its scene solved from zero, against
//! `…_fine_pass_geometry…`): all six within tolerance 77 → 86 of
//! 180 headline cases (no configuration worse), wide blur 12 → 18 of 80;
//! aligned RMSE dx 0.0064–0.047 → 0.0037–0.0044 px, dy 0.017–0.109 →
//! 0.0074–0.073 px, α 0.028–0.148 → 0.0096–0.102°; random poses mixed
//! (dx 0.063–0.153 → 0.065–0.136 px). Reported on the held-out half
//! (`calibrate_physical_held_out.json`).

use serde::{Deserialize, Serialize};

use super::scene_fit::FinePassFree;
use super::score::{CalibrationProblem, ProxyParams, gap_tv_reconstruction, proxy_reconstruction};
use crate::error::{CassiError, Result};
use crate::optics::blur::GaussianBlur;
use crate::params::Mismatch;

/// Settings of the detail pass.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DetailPass {
    /// σ of the Gaussian the proxy's luminance is smoothed by first, pixels.
    /// 1 by default; 0.5 measured on the tuning half's four configurations
    /// (`calibrate_physical_tuning_stop49/`): all six within tolerance 118
    /// → 120 of 180, the aligned instruments sharper (dx RMSE 0.014 →
    /// 0.006 px), the random poses unchanged (69 → 68 of 120): not adopted.
    pub pre_smooth_px: f64,
    /// σ of the Gaussian average the detail is taken against, pixels.
    pub detail_px: f64,
    /// Which parameters it refits (those of them the preset fits). Its
    /// floors ([`super::Fit::SceneDetailPass`]) were derived with the
    /// geometry (the default), σ held: the dispersed-mask model's own σ
    /// bias (about −0.06 px with the scene known) is what the smooth
    /// scene's cancels. The crisp-cell model with `All`:
    /// `calibrate_physical_tuning_crisp_cells_detail_pass_all.json`.
    pub free: FinePassFree,
    /// How many detail maps, each from the luminance of a group of
    /// consecutive bands (1: one grey map for every band). Absent in
    /// settings written before it: 1.
    #[serde(default = "one_group")]
    pub spectral_groups: usize,
    /// Above this first-pass blur σ (px) the pass solves its scene from
    /// zero instead of from the first pass's coefficients; `None`: always
    /// from them (as settings written before it ran). The default, 0.85
    /// px, parts the tuning half's wide-blur cases (first-pass σ ≥ 0.858)
    /// from all its others (≤ 0.811); on its 80 wide cases
    /// (`…_tuning_wide_detail_cold*.json` against `…_detail_pass*.json`)
    /// all six within tolerance 16 → 18, 1σ coverage dx 57 → 69, dy 59 →
    /// 63, α 58 → 65 (θ 70 → 66), dx RMSE 0.353 → 0.354 px, 1 s more per
    /// case; every other case unchanged.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cold_above_blur_px: Option<f64>,
    /// The reconstruction the maps are taken from. Absent in settings
    /// written before it: the proxy's.
    #[serde(default, skip_serializing_if = "DetailSource::is_proxy")]
    pub source: DetailSource,
    /// The pass's scene on this many spectral nodes instead of the first
    /// pass's (its coefficients carried over by least squares); `None`: the
    /// first pass's, as settings written before it ran, and by default. A
    /// probe of stop 67 (bench `--detail-pass-nodes N`): stop 65 saw the
    /// blind errors' pivot walk from the red end toward the scene-known
    /// fit's middle band in a detail and fine pass on 4 nodes, but a first
    /// pass on 4 biased the aligned instruments' a1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spectral_nodes: Option<usize>,
}

/// Where the detail maps' luminance comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DetailSource {
    /// The proxy reconstruction at the first pass's ψ (cheap; below about
    /// a pixel it carries the mask's imprint, whence the pre-smoothing).
    #[default]
    Proxy,
    /// GAP-TV's reconstruction at the first pass's ψ, this many iterations:
    /// closer to the scene, one solve dearer.
    GapTv { iterations: usize },
}

impl DetailSource {
    fn is_proxy(&self) -> bool {
        *self == Self::Proxy
    }
}

fn one_group() -> usize {
    1
}

impl Default for DetailPass {
    fn default() -> Self {
        Self {
            pre_smooth_px: 1.0,
            detail_px: 4.0,
            free: FinePassFree::Geometry,
            spectral_groups: 1,
            cold_above_blur_px: Some(0.85),
            source: DetailSource::Proxy,
            spectral_nodes: None,
        }
    }
}

/// A detail map below this share of the mean luminance's average is held
/// there (dark regions would divide by ≈ 0).
const DARK_SHARE: f32 = 0.02;
/// The detail map's range.
const DETAIL_RANGE: (f32, f32) = (0.05, 20.0);

impl DetailPass {
    /// The detail maps (groups × mask rows × cols) for `problem` from the
    /// proxy reconstruction at `at` (the proxy of `proxy`): group g's from
    /// the bands ⌊k·G/bands⌋ = g, the bands [`super::coarse_scene`] gives it.
    pub(crate) fn detail_map(
        &self,
        problem: &CalibrationProblem<'_>,
        at: &Mismatch,
        proxy: &ProxyParams,
    ) -> Result<Vec<f32>> {
        self.check(problem.bands())?;
        let (rows, cols) = problem.nominal_mask().shape();
        let cube = match self.source {
            DetailSource::Proxy => {
                let op = problem.operator(at)?;
                proxy_reconstruction(&op, problem.measurement, proxy)
            }
            DetailSource::GapTv { iterations } => {
                gap_tv_reconstruction(problem, at, iterations)?.into_vec()
            }
        };
        let (groups, plane) = (self.spectral_groups, rows * cols);
        let mut maps = Vec::with_capacity(groups * plane);
        for l in group_luminance(&cube, plane, groups).chunks_exact(plane) {
            maps.extend(detail_of(
                l,
                rows,
                cols,
                self.pre_smooth_px,
                self.detail_px,
            )?);
        }
        Ok(maps)
    }

    /// Its widths and groups for a cube of `bands` bands, named when out of
    /// range (a settings file's, say).
    pub(crate) fn check(&self, bands: usize) -> Result<()> {
        let groups = self.spectral_groups;
        if groups == 0 || groups > bands {
            return Err(CassiError::InvalidParameter {
                name: "detail_pass.spectral_groups",
                value: groups as f64,
                reason: format!("one detail map per group of bands: 1 to the cube's {bands}"),
            });
        }
        let widths = [
            ("detail_pass.pre_smooth_px", self.pre_smooth_px, 0.0),
            ("detail_pass.detail_px", self.detail_px, f64::MIN_POSITIVE),
        ];
        for (name, value, least) in widths {
            if !(value.is_finite() && value >= least && value <= MAX_WIDTH_PX) {
                return Err(CassiError::InvalidParameter {
                    name,
                    value,
                    reason: format!(
                        "a Gaussian width in pixels, {} to {MAX_WIDTH_PX}",
                        if least > 0.0 { "above 0" } else { "0" }
                    ),
                });
            }
        }
        if self.source == (DetailSource::GapTv { iterations: 0 }) {
            return Err(CassiError::InvalidParameter {
                name: "detail_pass.source.gap_tv.iterations",
                value: 0.0,
                reason: "GAP-TV's iterations for the detail maps: 1 or more".into(),
            });
        }
        if let Some(n) = self.spectral_nodes
            && !(2..=bands).contains(&n)
        {
            return Err(CassiError::InvalidParameter {
                name: "detail_pass.spectral_nodes",
                value: n as f64,
                reason: format!("spectral nodes: 2 to the cube's {bands} bands"),
            });
        }
        if let Some(px) = self.cold_above_blur_px
            && !(px.is_finite() && px >= 0.0)
        {
            return Err(CassiError::InvalidParameter {
                name: "detail_pass.cold_above_blur_px",
                value: px,
                reason: "a blur σ in pixels, 0 or more (absent: always from the first pass's \
                         scene)"
                    .into(),
            });
        }
        Ok(())
    }

    /// Whether the pass solves its scene from zero after a first pass that
    /// fitted the blur σ `first_pass_blur_px` (strictly above the threshold).
    pub(crate) fn starts_cold(&self, first_pass_blur_px: f64) -> bool {
        self.cold_above_blur_px
            .is_some_and(|px| first_pass_blur_px.abs() > px)
    }
}

/// The sum of a cube's bands (planes of `plane` pixels) in `groups`
/// groups of consecutive bands, band k in group ⌊k·groups/bands⌋.
fn group_luminance(cube: &[f32], plane: usize, groups: usize) -> Vec<f32> {
    let bands = cube.len() / plane.max(1);
    let mut luminance = vec![0.0f32; groups * plane];
    for (k, band) in cube.chunks_exact(plane).enumerate() {
        luminance[k * groups / bands * plane..][..plane]
            .iter_mut()
            .zip(band)
            .for_each(|(l, &v)| *l += v);
    }
    luminance
}

/// The widest smoothing the detail map takes, pixels (the blur's own limit).
const MAX_WIDTH_PX: f64 = crate::optics::blur::MAX_SIGMA_PX;

/// M_pre L / M_detail(M_pre L) of a luminance image `l` (rows × cols), M_s
/// the Gaussian local mean of width s ([`local_mean`]), held within
/// [`DETAIL_RANGE`], with averages below [`DARK_SHARE`] of the image's mean
/// raised to it; all ones for an image without light.
pub(crate) fn detail_of(
    l: &[f32],
    rows: usize,
    cols: usize,
    pre_smooth_px: f64,
    detail_px: f64,
) -> Result<Vec<f32>> {
    let smoothed = if pre_smooth_px > 0.0 {
        local_mean(l, rows, cols, pre_smooth_px)?
    } else {
        l.to_vec()
    };
    let average = local_mean(&smoothed, rows, cols, detail_px)?;
    let mean = smoothed.iter().map(|&v| v as f64).sum::<f64>() / l.len().max(1) as f64;
    if mean.is_nan() || mean <= 0.0 {
        // no light (or no finite light): no texture to give the scene
        return Ok(vec![1.0; l.len()]);
    }
    let dark = (DARK_SHARE * mean as f32).max(f32::MIN_POSITIVE);
    Ok(smoothed
        .iter()
        .zip(&average)
        .map(|(&v, &a)| (v.max(0.0) / a.max(dark)).clamp(DETAIL_RANGE.0, DETAIL_RANGE.1))
        .collect())
}

/// `maps` (one detail map per spectral group, each `mask`'s shape) with
/// their linear imprint of `mask` removed: the reconstruction's texture
/// regressed on the mask's own detail map (the same pre-smoothing and
/// width), the fitted share of it taken out. A random code carries no
/// scene texture, so what a map shares with it is the solver's imprint.
/// Returns the fitted shares (a probe's record, stop 70).
pub(crate) fn remove_mask_imprint(
    maps: &mut [f32],
    mask: &[f32],
    rows: usize,
    cols: usize,
    pre_smooth_px: f64,
    detail_px: f64,
) -> Result<Vec<f64>> {
    let code = detail_of(mask, rows, cols, pre_smooth_px, detail_px)?;
    let plane = rows * cols;
    let mut shares = Vec::new();
    for map in maps.chunks_exact_mut(plane) {
        let (mut cross, mut power) = (0.0f64, 0.0f64);
        for (&d, &m) in map.iter().zip(&code) {
            let m = m as f64 - 1.0;
            cross += (d as f64 - 1.0) * m;
            power += m * m;
        }
        let share = if power > 0.0 { cross / power } else { 0.0 };
        for (d, &m) in map.iter_mut().zip(&code) {
            *d = (*d - (share as f32) * (m - 1.0)).clamp(DETAIL_RANGE.0, DETAIL_RANGE.1);
        }
        shares.push(share);
    }
    Ok(shares)
}

/// The Gaussian-weighted mean of `image` around each pixel over the pixels
/// inside the frame (the blur of the image over the blur of ones: near the
/// edges the blur alone, zero outside, would read low).
fn local_mean(image: &[f32], rows: usize, cols: usize, sigma_px: f64) -> Result<Vec<f32>> {
    let blur = GaussianBlur::new(sigma_px, rows, cols)?;
    let mut tmp = vec![0.0f32; image.len()];
    let (mut sum, mut weight) = (vec![0.0f32; image.len()], vec![0.0f32; image.len()]);
    blur.apply(image, &mut sum, &mut tmp);
    blur.apply(&vec![1.0f32; image.len()], &mut weight, &mut tmp);
    sum.iter_mut()
        .zip(&weight)
        .for_each(|(s, &w)| *s /= w.max(f32::MIN_POSITIVE));
    Ok(sum)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A map that is a texture plus a share of the code's own detail gives
    /// that share back and loses the code: what is left is the texture's
    /// detail (the code, a random one, shares none of it). A map without
    /// the code keeps its texture.
    #[test]
    fn the_mask_imprint_is_regressed_out_of_a_detail_map() {
        let (rows, cols) = (128, 160);
        // a random 0/1 code and a smooth texture
        let mut state = 12345u64;
        let code: Vec<f32> = (0..rows * cols)
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 33) & 1) as f32
            })
            .collect();
        let texture: Vec<f32> = (0..rows * cols)
            .map(|i| 1.0 + 0.3 * ((i % cols) as f32 * 0.4).sin() * ((i / cols) as f32 * 0.3).cos())
            .collect();
        let code_detail = detail_of(&code, rows, cols, 1.0, 4.0).unwrap();
        let share = -0.25f32;
        let imprinted: Vec<f32> = texture
            .iter()
            .zip(&code_detail)
            .map(|(&t, &c)| t + share * (c - 1.0))
            .collect();
        let mut map = imprinted.clone();
        let shares = remove_mask_imprint(&mut map, &code, rows, cols, 1.0, 4.0).unwrap();
        assert_eq!(shares.len(), 1);
        assert!((shares[0] - share as f64).abs() < 0.03, "{shares:?}");
        let off = |m: &[f32]| {
            m.iter()
                .zip(&texture)
                .map(|(&a, &b)| ((a - b) as f64).powi(2))
                .sum::<f64>()
        };
        assert!(
            off(&map) < 0.02 * off(&imprinted),
            "{} {}",
            off(&map),
            off(&imprinted)
        );
        // no imprint: the texture stays (within the small share the fit reads)
        let mut clean = texture.clone();
        let shares = remove_mask_imprint(&mut clean, &code, rows, cols, 1.0, 4.0).unwrap();
        assert!(shares[0].abs() < 0.03, "{shares:?}");
        assert!(off(&clean) < 0.02 * off(&imprinted));
    }

    /// A flat image has no detail; a texture's detail is its ratio to its
    /// average: above 1 on the bright stripes, below on the dark ones, ≈ 1
    /// on average, at the frame's edges too; an image of 0 has none; a width
    /// out of range is named.
    #[test]
    fn the_detail_is_the_image_over_its_average() {
        let (rows, cols) = (32, 40);
        let flat = vec![3.0f32; rows * cols];
        let d = detail_of(&flat, rows, cols, 1.0, 4.0).unwrap();
        assert!(
            d.iter().all(|&v| (v - 1.0).abs() < 1e-4),
            "flat: {:?}",
            &d[..4]
        );

        let stripes: Vec<f32> = (0..rows * cols)
            .map(|i| if (i % cols) / 3 % 2 == 0 { 2.0 } else { 1.0 })
            .collect();
        let d = detail_of(&stripes, rows, cols, 0.0, 4.0).unwrap();
        let centre = (rows / 2) * cols;
        for c in 8..cols - 8 {
            let (v, s) = (d[centre + c], stripes[centre + c]);
            assert!((s > 1.5) == (v > 1.0), "col {c}: stripe {s}, detail {v}");
        }
        let mean: f32 = d[centre + 8..centre + cols - 8].iter().sum::<f32>() / (cols - 16) as f32;
        assert!((mean - 1.0).abs() < 0.05, "{mean}");

        let dark = detail_of(&vec![0.0f32; rows * cols], rows, cols, 1.0, 4.0).unwrap();
        assert!(dark.iter().all(|&v| v == 1.0));

        for groups in [0, 29] {
            let pass = DetailPass {
                spectral_groups: groups,
                ..DetailPass::default()
            };
            let e = pass.check(28).unwrap_err().to_string();
            assert!(e.contains("detail_pass.spectral_groups"), "{e}");
        }
        let colour = DetailPass {
            spectral_groups: 28,
            ..DetailPass::default()
        };
        assert!(colour.check(28).is_ok());

        for bad in [0.0, -1.0, f64::NAN, 1e9] {
            let pass = DetailPass {
                detail_px: bad,
                ..DetailPass::default()
            };
            let e = pass.check(28).unwrap_err().to_string();
            assert!(e.contains("detail_pass.detail_px"), "{e}");
        }
        let pass = DetailPass {
            pre_smooth_px: -0.5,
            ..DetailPass::default()
        };
        assert!(
            pass.check(28)
                .unwrap_err()
                .to_string()
                .contains("pre_smooth_px")
        );
        assert!(DetailPass::default().check(28).is_ok());
        for nodes in [1, 29] {
            let pass = DetailPass {
                spectral_nodes: Some(nodes),
                ..DetailPass::default()
            };
            let e = pass.check(28).unwrap_err().to_string();
            assert!(e.contains("detail_pass.spectral_nodes"), "{e}");
        }
        let own = DetailPass {
            spectral_nodes: Some(4),
            ..DetailPass::default()
        };
        assert!(own.check(28).is_ok());
        // settings without the field read as the first pass's nodes, and
        // the default writes none
        let json = serde_json::to_string(&DetailPass::default()).unwrap();
        assert!(!json.contains("spectral_nodes"), "{json}");
        let read: DetailPass = serde_json::from_str(&serde_json::to_string(&own).unwrap()).unwrap();
        assert_eq!(read, own);
    }

    /// Groups are consecutive bands, as the coarse scene assigns the maps:
    /// 7 bands in 3 groups sum bands 0–2, 3–4 and 5–6.
    #[test]
    fn groups_sum_consecutive_bands() {
        let plane = 2;
        let cube: Vec<f32> = (0..7).flat_map(|k| [k as f32, 10.0 * k as f32]).collect();
        let l = group_luminance(&cube, plane, 3);
        // ⌊3k/7⌋: k 0,1,2 → 0; 3,4 → 1; 5,6 → 2
        assert_eq!(l, vec![3.0, 30.0, 7.0, 70.0, 11.0, 110.0]);
        assert_eq!(group_luminance(&cube, plane, 1), vec![21.0, 210.0]);
    }

    /// Settings written before the cold start above a blur existed read as
    /// always warm, and a threshold round-trips.
    #[test]
    fn the_cold_start_threshold_is_optional_in_settings() {
        let warm = DetailPass {
            cold_above_blur_px: None,
            ..DetailPass::default()
        };
        let plain = serde_json::to_value(warm).unwrap();
        assert!(plain.get("cold_above_blur_px").is_none());
        let back: DetailPass = serde_json::from_value(plain).unwrap();
        assert_eq!(back.cold_above_blur_px, None);
        let cold = DetailPass::default();
        assert_eq!(cold.cold_above_blur_px, Some(0.85));
        let json = serde_json::to_string(&cold).unwrap();
        assert_eq!(serde_json::from_str::<DetailPass>(&json).unwrap(), cold);
    }

    /// Settings written before the source existed read as the proxy's, the
    /// proxy is not written out (older readers and settings digests see
    /// nothing new), GAP-TV's round-trips, and zero iterations are refused
    /// by name.
    #[test]
    fn the_detail_source_is_the_proxy_unless_named() {
        let plain = serde_json::to_value(DetailPass::default()).unwrap();
        assert!(plain.get("source").is_none(), "{plain}");
        let back: DetailPass = serde_json::from_value(plain).unwrap();
        assert_eq!(back.source, DetailSource::Proxy);
        let gap = DetailPass {
            source: DetailSource::GapTv { iterations: 30 },
            ..DetailPass::default()
        };
        let json = serde_json::to_value(gap).unwrap();
        assert_eq!(json["source"]["gap_tv"]["iterations"], 30, "{json}");
        assert_eq!(serde_json::from_value::<DetailPass>(json).unwrap(), gap);
        assert!(gap.check(28).is_ok());
        let e = DetailPass {
            source: DetailSource::GapTv { iterations: 0 },
            ..gap
        }
        .check(28)
        .unwrap_err()
        .to_string();
        assert!(e.contains("detail_pass.source.gap_tv.iterations"), "{e}");
    }

    /// The default starts cold only above 0.85 px (the tuning half's wide
    /// cases), never without a threshold, and a threshold that is not a
    /// width is refused by name.
    #[test]
    fn the_pass_starts_cold_only_above_its_threshold() {
        let pass = DetailPass::default();
        assert!(!pass.starts_cold(0.5) && !pass.starts_cold(0.85));
        assert!(pass.starts_cold(0.858) && pass.starts_cold(1.2));
        let warm = DetailPass {
            cold_above_blur_px: None,
            ..pass
        };
        assert!(!warm.starts_cold(5.0));
        assert!(warm.check(28).is_ok() && pass.check(28).is_ok());
        for bad in [-0.1, f64::NAN, f64::INFINITY] {
            let e = DetailPass {
                cold_above_blur_px: Some(bad),
                ..pass
            }
            .check(28)
            .unwrap_err()
            .to_string();
            assert!(e.contains("detail_pass.cold_above_blur_px"), "{e}");
        }
    }
}
