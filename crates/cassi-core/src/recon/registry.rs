//! Every reconstruction method cassi knows, in one table: its name, its
//! kind, where its weights come from and the shapes it was trained for.
//! Compiled with or without the networks, so a build without them can still
//! name them, list them and say how to get them. A method name is parsed to
//! a [`MethodId`] here and compared nowhere else; adding a network is its
//! module in cassi-nets plus one entry of [`METHODS`].

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::error::{CassiError, Result};

/// Bands of the networks' training data (the MST toolbox's 28).
pub const NETWORK_BANDS: usize = 28;
/// Detector columns per band the networks were trained with.
pub const NETWORK_STEP: usize = 2;
/// MST's fixed spatial size (its mask shift-back is built for it).
pub const MST_SIZE: usize = 256;

/// A method, typed. The discriminant indexes [`METHODS`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MethodId {
    GapTv,
    AdmmTv,
    PnpTv,
    MstS,
    MstL,
    HdNet,
    PnpHsicnn,
}

/// How a method reconstructs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MethodKind {
    /// A cassi-core solver with a hand-made prior (no weights).
    Iterative,
    /// A pretrained feed-forward network: no iterations, its trained
    /// dispersion, guided (or not) by the posed mask.
    Network,
    /// A cassi-core solver with a learned denoiser: the whole model, iterations.
    LearnedPnp,
}

impl MethodKind {
    /// Needs a weights file and a build with the `nets` feature.
    pub fn is_learned(self) -> bool {
        self != Self::Iterative
    }

    /// Runs a solver, so an iteration count applies.
    pub fn has_iterations(self) -> bool {
        self != Self::Network
    }
}

/// Where a learned method's weights come from and what they are called.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WeightHint {
    /// Where a user gets the official weights.
    pub official: &'static str,
    /// File stems tried in a weights folder after the method's own name
    /// (as is and with `-` → `_`).
    pub extra_stems: &'static [&'static str],
}

/// The inputs a method was trained for; `None`: any.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShapeRules {
    pub bands: Option<usize>,
    /// Nominal dispersion stride, detector columns per band.
    pub stride: Option<usize>,
    /// (rows, cols) of the scene and mask.
    pub size: Option<(usize, usize)>,
}

impl ShapeRules {
    const ANY: Self = Self {
        bands: None,
        stride: None,
        size: None,
    };
}

/// One row of the registry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MethodSpec {
    pub id: MethodId,
    pub name: &'static str,
    pub kind: MethodKind,
    /// `Some` exactly for learned methods.
    pub weights: Option<WeightHint>,
    pub shape: ShapeRules,
}

const MST_ZOO: &str = "the MST toolbox's model zoo (github.com/caiyuanhao1998/MST, linked from \
                       its README: mst_s.pth, mst_l.pth, hdnet.pth)";

const MST_SHAPE: ShapeRules = ShapeRules {
    bands: Some(NETWORK_BANDS),
    stride: Some(NETWORK_STEP),
    size: Some((MST_SIZE, MST_SIZE)),
};

const fn iterative(id: MethodId, name: &'static str) -> MethodSpec {
    MethodSpec {
        id,
        name,
        kind: MethodKind::Iterative,
        weights: None,
        shape: ShapeRules::ANY,
    }
}

const fn network(id: MethodId, name: &'static str, shape: ShapeRules) -> MethodSpec {
    MethodSpec {
        id,
        name,
        kind: MethodKind::Network,
        weights: Some(WeightHint {
            official: MST_ZOO,
            extra_stems: &[],
        }),
        shape,
    }
}

/// The registry, in the order methods are listed to users (solvers first).
pub const METHODS: [MethodSpec; 7] = [
    iterative(MethodId::GapTv, "gap-tv"),
    iterative(MethodId::AdmmTv, "admm-tv"),
    iterative(MethodId::PnpTv, "pnp-tv"),
    network(MethodId::MstS, "mst-s", MST_SHAPE),
    network(MethodId::MstL, "mst-l", MST_SHAPE),
    // HDNet never sees the mask, so any spatial size goes
    network(
        MethodId::HdNet,
        "hdnet",
        ShapeRules {
            size: None,
            ..MST_SHAPE
        },
    ),
    MethodSpec {
        id: MethodId::PnpHsicnn,
        name: "pnp-hsicnn",
        kind: MethodKind::LearnedPnp,
        weights: Some(WeightHint {
            official: "the HSI-SDeCNN denoiser of PnP-CASSI (github.com/zsm1211/PnP-CASSI, \
                       check_points/deep_denoiser.pth)",
            extra_stems: &["deep_denoiser", "hsi_sdecnn"],
        }),
        // a model-based solver; its denoiser slides a 7-band window
        shape: ShapeRules::ANY,
    },
];

/// The names of the methods of `kind`, in registry order.
pub fn names_of(kind: MethodKind) -> impl Iterator<Item = &'static str> {
    METHODS
        .iter()
        .filter(move |s| s.kind == kind)
        .map(|s| s.name)
}

/// The names of the learned methods (networks and learned PnP).
pub fn learned_names() -> impl Iterator<Item = &'static str> {
    METHODS
        .iter()
        .filter(|s| s.kind.is_learned())
        .map(|s| s.name)
}

/// Every name, in registry order.
pub fn all_names() -> impl Iterator<Item = &'static str> {
    METHODS.iter().map(|s| s.name)
}

impl MethodId {
    /// The method called `name`; an unknown name's error lists the known ones.
    pub fn parse(name: &str) -> Result<Self> {
        METHODS
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.id)
            .ok_or_else(|| CassiError::InvalidParameter {
                name: "method",
                value: f64::NAN,
                reason: format!(
                    "unknown method '{name}' (known: {})",
                    all_names().collect::<Vec<_>>().join(", ")
                ),
            })
    }

    pub fn spec(self) -> &'static MethodSpec {
        &METHODS[self as usize]
    }

    pub fn name(self) -> &'static str {
        self.spec().name
    }

    pub fn kind(self) -> MethodKind {
        self.spec().kind
    }

    /// File names tried for this method's weights in a weights folder, in
    /// order (none for a method without weights).
    pub fn weight_file_names(self) -> Vec<String> {
        let Some(hint) = self.spec().weights else {
            return Vec::new();
        };
        let name = self.name();
        let mut stems = vec![name.to_string(), name.replace('-', "_")];
        stems.extend(hint.extra_stems.iter().map(|s| s.to_string()));
        stems.dedup();
        stems
            .iter()
            .flat_map(|s| [format!("{s}.pth"), format!("{s}.safetensors")])
            .collect()
    }
}

impl FromStr for MethodId {
    type Err = CassiError;
    fn from_str(name: &str) -> Result<Self> {
        Self::parse(name)
    }
}

impl fmt::Display for MethodId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Written as its name, so records read as before the registry existed.
impl Serialize for MethodId {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for MethodId {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        Self::parse(&name).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_parses_back_to_its_own_entry() {
        for (i, spec) in METHODS.iter().enumerate() {
            assert_eq!(
                spec.id as usize, i,
                "{} is not at its id's index",
                spec.name
            );
            let id = MethodId::parse(spec.name).unwrap();
            assert_eq!(
                (id, id.name(), id.to_string()),
                (spec.id, spec.name, spec.name.into())
            );
            let json = serde_json::to_value(id).unwrap();
            assert_eq!(json, serde_json::json!(spec.name));
            assert_eq!(serde_json::from_value::<MethodId>(json).unwrap(), id);
        }
        let mut names: Vec<_> = all_names().collect();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), METHODS.len(), "a name is listed twice");
    }

    #[test]
    fn an_unknown_name_lists_the_known_ones() {
        let e = MethodId::parse("mst-xl").unwrap_err().to_string();
        assert!(e.contains("unknown method 'mst-xl'"), "{e}");
        for name in all_names() {
            assert!(e.contains(name), "{name} missing from: {e}");
        }
        assert!("GAP-TV".parse::<MethodId>().is_err());
    }

    #[test]
    fn learned_methods_and_only_they_have_weights() {
        for spec in &METHODS {
            assert_eq!(
                spec.weights.is_some(),
                spec.kind.is_learned(),
                "{}",
                spec.name
            );
        }
        assert_eq!(
            MethodId::PnpHsicnn.weight_file_names(),
            [
                "pnp-hsicnn.pth",
                "pnp-hsicnn.safetensors",
                "pnp_hsicnn.pth",
                "pnp_hsicnn.safetensors",
                "deep_denoiser.pth",
                "deep_denoiser.safetensors",
                "hsi_sdecnn.pth",
                "hsi_sdecnn.safetensors"
            ]
        );
        // no '-' in the name: one stem, not two
        assert_eq!(
            MethodId::HdNet.weight_file_names(),
            ["hdnet.pth", "hdnet.safetensors"]
        );
        assert!(MethodId::GapTv.weight_file_names().is_empty());
    }
}
