//! HSI-SDeCNN against PyTorch (README §6 of shared/data/nets): the 64² case
//! and the odd 37×50 case (replicate padding and crop).

mod common;

use cassi_nets::HsiSdecnn;
use common::{check, nets_dir, npy};

#[test]
fn hsi_sdecnn_matches_pytorch() {
    let Some(nets) = nets_dir("hsi_sdecnn_matches_pytorch") else {
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
