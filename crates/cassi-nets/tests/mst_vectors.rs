//! MST-S (official weights) and MST-L (seed-0 weights) against PyTorch
//! (README §4 of shared/data/nets), including MST-S's activation dumps,
//! which localise a wrong layer.

mod common;

use std::time::Instant;

use cassi_nets::{Mst, MstConfig};
use common::{check, mst_inputs, nets_dir, npy, top_rows};

#[test]
fn mst_s_matches_pytorch_output_and_activations() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let d = nets.join("mst_s");
    let net = Mst::load(d.join("mst_s.safetensors"), MstConfig::SMALL).unwrap();
    let (h, phi) = mst_inputs(&nets);
    let t = Instant::now();
    let (out, acts) = net.forward_with_activations(&h, &phi).unwrap();
    eprintln!("MST-S forward: {:.2} s", t.elapsed().as_secs_f64());
    // The mask half computed once and reused gives the same numbers, and only
    // to the network that computed it.
    let guidance = net.mask_guidance(&phi).unwrap();
    let t = Instant::now();
    let guided = net.forward_guided(&h, &guidance).unwrap();
    eprintln!(
        "MST-S forward with precomputed mask guidance: {:.2} s",
        t.elapsed().as_secs_f64()
    );
    assert_eq!(guided, out, "forward_guided differs from forward");
    let other = Mst::load(d.join("mst_s.safetensors"), MstConfig::SMALL).unwrap();
    let e = other.forward_guided(&h, &guidance).unwrap_err().to_string();
    assert!(e.contains("another MST instance"), "{e}");
    for (name, got) in [
        ("act_embedding_rows0-32", top_rows(&acts.embedding, 32)),
        (
            "act_enc0_block0_mask_attn_rows0-32",
            top_rows(&acts.enc0_block0_mask_attn, 32),
        ),
        ("act_enc0_msab_rows0-32", top_rows(&acts.enc0_msab, 32)),
        ("act_bottleneck", acts.bottleneck.clone()),
        ("act_mapping_rows0-32", top_rows(&acts.mapping, 32)),
        ("out", out),
    ] {
        check(
            &format!("mst_s/{name}.npy"),
            &got,
            &npy(d.join(format!("{name}.npy"))),
            1e-4,
        );
    }
}

#[test]
fn mst_l_matches_pytorch() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let net = Mst::load(nets.join("mst_l/mst_l_seed0.safetensors"), MstConfig::LARGE).unwrap();
    let (h, phi) = mst_inputs(&nets);
    let t = Instant::now();
    let out = net.forward(&h, &phi).unwrap();
    eprintln!("MST-L forward: {:.2} s", t.elapsed().as_secs_f64());
    check(
        "mst_l/out.npy",
        &out,
        &npy(nets.join("mst_l/out.npy")),
        1e-4,
    );
}

/// The by-name entry point: official MST-S from the `.pth`, measurement and
/// mask in, cube out — the same numbers as the tensor API.
#[test]
fn reconstructor_runs_mst_s_from_the_official_pth() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let weights = nets.join("../weights/mst_s.pth");
    let net = cassi_nets::Network::load(cassi_core::recon::MethodId::MstS, weights)
        .unwrap_or_else(|e| panic!("{e}"));
    let y = npy(nets.join("common/y.npy"));
    let mask = npy(nets.join("common/mask.npy"));
    let y = cassi_core::Measurement::from_vec(256, 310, y.into_data()).unwrap();
    let mask = cassi_core::Mask::from_vec(256, 256, mask.into_data()).unwrap();
    let r = net
        .reconstruct(&y, &mask, &cassi_core::MaskPose::default())
        .unwrap();
    assert_eq!(r.width_fitted, None);
    let cube = r.cube;
    assert_eq!(cube.shape(), (28, 256, 256));
    let got = cassi_nets::Tensor::new(vec![1, 28, 256, 256], cube.into_vec()).unwrap();
    check(
        "Network mst-s (.pth) vs mst_s/out.npy",
        &got,
        &npy(nets.join("mst_s/out.npy")),
        1e-4,
    );
    // a registry id that is not a network does not load as one
    let e = cassi_nets::Network::load(cassi_core::recon::MethodId::PnpHsicnn, "x");
    assert!(e.is_err_and(|e| e.to_string().contains("mst-s, mst-l, hdnet")));
}
