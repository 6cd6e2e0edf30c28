//! HDNet against PyTorch (README §5 of shared/data/nets): seed-0 weights at
//! 256², and the stress variant (large BatchNorm and SDL weights) at 64²,
//! which fails on any wrong DSC, BatchNorm or SDL detail.

mod common;

use std::time::Instant;

use cassi_nets::{HdNet, TensorMap};
use common::{check, mst_inputs, nets_dir, npy};

#[test]
fn hdnet_matches_pytorch() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let net = HdNet::load(nets.join("hdnet/hdnet_seed0.safetensors")).unwrap();
    let (h, _) = mst_inputs(&nets);
    let t = Instant::now();
    let out = net.forward(&h).unwrap();
    eprintln!("HDNet forward: {:.2} s", t.elapsed().as_secs_f64());
    check(
        "hdnet/out.npy",
        &out,
        &npy(nets.join("hdnet/out.npy")),
        1e-4,
    );
}

#[test]
fn hdnet_stress_variant_matches_pytorch() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let d = nets.join("hdnet");
    let mut weights = TensorMap::load(d.join("hdnet_seed0.safetensors")).unwrap();
    weights
        .overlay(TensorMap::load(d.join("stress_override.safetensors")).unwrap())
        .unwrap();
    let net = HdNet::from_tensors(weights).unwrap();
    let out = net.forward(&npy(d.join("stress_in.npy"))).unwrap();
    check(
        "hdnet/stress_out.npy",
        &out,
        &npy(d.join("stress_out.npy")),
        1e-4,
    );
}
