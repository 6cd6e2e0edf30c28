//! Feature-map storage is recycled: once a network has run, running it
//! again takes every large buffer from the pool, so the pool neither grows
//! nor churns (a buffer allocated outside the pool and dropped into it
//! would grow it by one map per pass, up to its bound). One test per file:
//! the pool is process-wide.

mod common;

use cassi_nets::{HdNet, Mst, MstConfig, Tensor, cached_buffer_bytes, release_cached_buffers};
use common::{mst_inputs, nets_dir};

#[test]
fn repeated_forward_passes_reuse_the_same_buffers() {
    let Some(nets) = nets_dir() else {
        return;
    };
    release_cached_buffers();
    let mst = Mst::load(nets.join("mst_s/mst_s.safetensors"), MstConfig::SMALL).unwrap();
    let (h, phi) = mst_inputs(&nets);
    let hdnet = HdNet::load(nets.join("hdnet/hdnet_seed0.safetensors")).unwrap();
    // 96² × 64 channels: HDNet's maps are above the pool's 1 MiB threshold.
    let small = Tensor::new(vec![1, 28, 96, 96], vec![0.25; 28 * 96 * 96]).unwrap();
    let mut cached = Vec::new();
    for _ in 0..3 {
        mst.forward(&h, &phi).unwrap();
        hdnet.forward(&small).unwrap();
        cached.push(cached_buffer_bytes());
    }
    assert!(cached[0] > 0, "large maps are kept for reuse");
    assert_eq!(cached[1], cached[0], "second pass: {cached:?}");
    assert_eq!(cached[2], cached[0], "third pass: {cached:?}");
    assert!(cached[0] <= cassi_nets::MAX_POOLED_BYTES);
}
