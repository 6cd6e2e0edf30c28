//! `toolbox_inputs` rebuilds H and Phi bit for bit as the reference's
//! `common/make_inputs.py` (SHA-256 of the raw float32 data from meta.json);
//! the digest of y.npy itself is checked too, so a wrong hash cannot pass.

mod common;

use common::sha256::{sha256_f32, sha256_hex};
use common::{mst_inputs, nets_dir, npy};

#[test]
fn h_and_phi_match_the_reference_bit_for_bit() {
    let Some(nets) = nets_dir() else {
        return;
    };
    let y = npy(nets.join("common/y.npy"));
    assert_eq!(
        sha256_f32(y.data()),
        "9c64eb156212e3987160cfcb7e0ef2142af0fa6f3baf72230aa0a204d922a450",
        "y.npy"
    );
    let (h, phi) = mst_inputs(&nets);
    assert_eq!(
        sha256_f32(h.data()),
        "3b30543d830ef8b778738edcf3c2b4153d75da87985893878b27e7b308df1c0e",
        "H"
    );
    assert_eq!(
        sha256_f32(phi.data()),
        "73479987fadb401f9c2ce200aa147d7d7c93528dd9443bd2e2d2d5310ac80ebe",
        "Phi"
    );
}

#[test]
fn sha256_matches_the_standard_abc_vector() {
    assert_eq!(
        sha256_hex(b"abc"),
        "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
    );
}
