//! HSI-SDeCNN against PyTorch (README §6 of shared/data/nets): the 64² case
//! and the odd 37×50 case (replicate padding and crop).

mod common;

use cassi_nets::HsiSdecnn;
use common::{check, nets_dir, npy};

#[test]
fn hsi_sdecnn_matches_pytorch() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let d = nets.join("hsi_sdecnn");
    let net = HsiSdecnn::load(d.join("hsi_sdecnn_seed0.safetensors")).unwrap();
    for (input, sigma, out) in [
        ("in.npy", "sigma.npy", "out.npy"),
        ("odd_in.npy", "odd_sigma.npy", "odd_out.npy"),
    ] {
        let got = net
            .forward(&npy(d.join(input)), &npy(d.join(sigma)))
            .unwrap();
        check(&format!("hsi_sdecnn/{out}"), &got, &npy(d.join(out)), 1e-4);
    }
}

/// The cube denoiser feeds band i the stack i−3 … i+3 of the input cube:
/// on a cube whose bands 11–17 are the test input, band 14 of the result is
/// the network's output on that input.
#[test]
fn cube_denoiser_denoises_each_band_from_its_stack() {
    use cassi_core::{Cube, Denoiser};
    use cassi_nets::HsiSdecnnDenoiser;
    let Some(nets) = nets_dir() else {
        return;
    };
    let d = nets.join("hsi_sdecnn");
    let net = HsiSdecnn::load(d.join("hsi_sdecnn_seed0.safetensors")).unwrap();
    let input = npy(d.join("in.npy")); // (1, 7, 64, 64) = bands 11..=17
    let plane = 64 * 64;
    let mut data = vec![0.0f32; 20 * plane];
    data[11 * plane..18 * plane].copy_from_slice(input.data());
    let mut cube = Cube::from_vec(20, 64, 64, data).unwrap();
    let mut den = HsiSdecnnDenoiser::new(net);
    den.denoise(&mut cube, npy(d.join("sigma.npy")).data()[0]);
    let band14 = cassi_nets::Tensor::new(vec![1, 1, 64, 64], cube.band(14).to_vec()).unwrap();
    check(
        "denoiser band 14 vs hsi_sdecnn/out.npy",
        &band14,
        &npy(d.join("out.npy")),
        1e-4,
    );
}
