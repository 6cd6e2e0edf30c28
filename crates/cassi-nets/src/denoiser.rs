//! HSI-SDeCNN as a plug-and-play [`Denoiser`] of whole cubes, the way
//! PnP-CASSI uses it: band i is denoised from bands i−3 … i+3, with the
//! band index clamped at the edges (band 0 sees [0, 0, 0, 0, 1, 2, 3]).

use cassi_core::{Cube, Denoiser};

use crate::fmap::FeatureMap;
use crate::hsi_sdecnn::HsiSdecnn;

pub struct HsiSdecnnDenoiser {
    net: HsiSdecnn,
}

impl HsiSdecnnDenoiser {
    pub fn new(net: HsiSdecnn) -> Self {
        Self { net }
    }

    /// Band indices of the 7-band stack centred on `band` of `bands`.
    pub fn stack_bands(band: usize, bands: usize) -> [usize; 7] {
        std::array::from_fn(|j| (band + j).saturating_sub(3).min(bands - 1))
    }
}

impl Denoiser for HsiSdecnnDenoiser {
    /// Every band is denoised from the input cube (not from already
    /// denoised neighbours); `strength` is the noise σ on the cube's scale
    /// (PnP-CASSI uses 10/255 for cubes in [0, 1]).
    fn denoise(&mut self, cube: &mut Cube, strength: f32) {
        let (bands, h, w) = cube.shape();
        if bands == 0 || h == 0 || w == 0 {
            return;
        }
        let plane = h * w;
        // Pooled storage for the stacks and outputs (see `buffer_pool`).
        let denoised: Vec<FeatureMap> = (0..bands)
            .map(|b| {
                let mut stack = FeatureMap::for_overwrite(HsiSdecnn::IN_BANDS, h, w);
                for (dst, k) in stack
                    .data
                    .chunks_mut(plane)
                    .zip(Self::stack_bands(b, bands))
                {
                    dst.copy_from_slice(cube.band(k));
                }
                self.net.denoise_stack(&stack, strength)
            })
            .collect();
        for (b, band) in denoised.iter().enumerate() {
            cube.band_mut(b).copy_from_slice(&band.data);
        }
    }

    fn name(&self) -> String {
        "hsi-sdecnn".into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edge_bands_replicate_as_pnp_cassi() {
        assert_eq!(HsiSdecnnDenoiser::stack_bands(0, 31), [0, 0, 0, 0, 1, 2, 3]);
        assert_eq!(HsiSdecnnDenoiser::stack_bands(1, 31), [0, 0, 0, 1, 2, 3, 4]);
        assert_eq!(HsiSdecnnDenoiser::stack_bands(2, 31), [0, 0, 1, 2, 3, 4, 5]);
        assert_eq!(
            HsiSdecnnDenoiser::stack_bands(10, 31),
            [7, 8, 9, 10, 11, 12, 13]
        );
        assert_eq!(
            HsiSdecnnDenoiser::stack_bands(30, 31),
            [27, 28, 29, 30, 30, 30, 30]
        );
        assert_eq!(HsiSdecnnDenoiser::stack_bands(0, 1), [0; 7]);
    }
}
