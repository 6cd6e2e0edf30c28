//! The learned methods a study can run, where their official weights come
//! from, and finding a weights file for each (a per-method file, or a
//! folder searched by conventional names).

use std::path::{Path, PathBuf};

use anyhow::bail;

/// Pretrained networks (MST-S, MST-L, HDNet) and PnP with the HSI-SDeCNN
/// denoiser; all need a weights file and a build with the `nets` feature.
pub const LEARNED_METHOD_NAMES: [&str; 4] = ["mst-s", "mst-l", "hdnet", "pnp-hsicnn"];

/// True when this build can run the learned methods (feature `nets`).
pub const NETS_BUILT: bool = cfg!(feature = "nets");

pub fn is_learned(method: &str) -> bool {
    LEARNED_METHOD_NAMES.contains(&method)
}

/// Where a user gets the official weights of `method`.
pub fn official_weights(method: &str) -> &'static str {
    match method {
        "pnp-hsicnn" => {
            "the HSI-SDeCNN denoiser of PnP-CASSI (github.com/zsm1211/PnP-CASSI, \
             check_points/deep_denoiser.pth)"
        }
        _ => {
            "the MST toolbox's model zoo (github.com/caiyuanhao1998/MST, linked from its \
             README: mst_s.pth, mst_l.pth, hdnet.pth)"
        }
    }
}

/// File names tried for `method` in a weights folder, in order.
pub fn candidate_files(method: &str) -> Vec<String> {
    let mut stems = vec![method.to_string(), method.replace('-', "_")];
    if method == "pnp-hsicnn" {
        stems.extend(["deep_denoiser".to_string(), "hsi_sdecnn".to_string()]);
    }
    stems.dedup();
    stems
        .iter()
        .flat_map(|s| [format!("{s}.pth"), format!("{s}.safetensors")])
        .collect()
}

/// The weights file of learned method `method`: the one given for it in
/// `given` (`--weights METHOD=FILE`), else the first of
/// [`candidate_files`] in `dir` (`--weights-dir`). Errors say what was
/// tried and where official weights come from.
pub fn resolve_weights(
    method: &str,
    given: &[(String, PathBuf)],
    dir: Option<&Path>,
) -> anyhow::Result<PathBuf> {
    if let Some((_, path)) = given.iter().find(|(m, _)| m == method) {
        if !path.is_file() {
            bail!(
                "--weights {method}={}: no such file (official weights: {})",
                path.display(),
                official_weights(method)
            );
        }
        return Ok(path.clone());
    }
    let Some(dir) = dir else {
        bail!(
            "--methods {method} needs weights: --weights {method}=FILE or --weights-dir DIR \
             (official weights: {})",
            official_weights(method)
        );
    };
    let names = candidate_files(method);
    if let Some(found) = names.iter().map(|n| dir.join(n)).find(|p| p.is_file()) {
        return Ok(found);
    }
    bail!(
        "--weights-dir {}: no weights for {method} (looked for {}); official weights: {}",
        dir.display(),
        names.join(", "),
        official_weights(method)
    )
}

/// Parses `--weights METHOD=FILE` values, refusing unknown or repeated
/// methods and methods the study does not run (a typo would otherwise be
/// silently ignored).
pub fn parse_weight_flags(
    flags: &[String],
    methods: &[String],
) -> anyhow::Result<Vec<(String, PathBuf)>> {
    let mut out: Vec<(String, PathBuf)> = Vec::new();
    for flag in flags {
        let Some((method, path)) = flag.split_once('=') else {
            bail!("--weights {flag}: expected METHOD=FILE, e.g. --weights mst-s=mst_s.pth");
        };
        let method = method.trim();
        if !is_learned(method) {
            bail!(
                "--weights {flag}: '{method}' is not a learned method (known: {})",
                LEARNED_METHOD_NAMES.join(", ")
            );
        }
        if !methods.iter().any(|m| m == method) {
            bail!("--weights {flag}: --methods does not include {method}");
        }
        if out.iter().any(|(m, _)| m == method) {
            bail!("--weights: {method} is given twice");
        }
        out.push((method.to_string(), PathBuf::from(path)));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("cassi-eval-weights-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_folder_is_searched_by_conventional_names() {
        let dir = scratch("folder");
        std::fs::write(dir.join("mst_s.pth"), b"x").unwrap();
        std::fs::write(dir.join("deep_denoiser.pth"), b"x").unwrap();
        assert_eq!(
            resolve_weights("mst-s", &[], Some(&dir)).unwrap(),
            dir.join("mst_s.pth")
        );
        assert_eq!(
            resolve_weights("pnp-hsicnn", &[], Some(&dir)).unwrap(),
            dir.join("deep_denoiser.pth")
        );
        let e = resolve_weights("hdnet", &[], Some(&dir))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("hdnet.pth")
                && e.contains("hdnet.safetensors")
                && e.contains("caiyuanhao1998/MST"),
            "{e}"
        );
        // a per-method file wins over the folder
        let own = dir.join("own.safetensors");
        std::fs::write(&own, b"x").unwrap();
        let given = vec![("mst-s".to_string(), own.clone())];
        assert_eq!(resolve_weights("mst-s", &given, Some(&dir)).unwrap(), own);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn missing_weights_say_where_official_ones_come_from() {
        let e = resolve_weights("pnp-hsicnn", &[], None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--weights pnp-hsicnn=FILE") && e.contains("zsm1211/PnP-CASSI"),
            "{e}"
        );
        let given = vec![("mst-l".to_string(), PathBuf::from("/nonexistent/mst_l.pth"))];
        let e = resolve_weights("mst-l", &given, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/nonexistent/mst_l.pth") && e.contains("no such file"),
            "{e}"
        );
    }

    #[test]
    fn weight_flags_are_checked() {
        let methods = vec!["gap-tv".to_string(), "mst-s".to_string()];
        let ok = parse_weight_flags(&["mst-s=a/b.pth".into()], &methods).unwrap();
        assert_eq!(ok, vec![("mst-s".to_string(), PathBuf::from("a/b.pth"))]);
        for (flag, needle) in [
            ("mst-s", "METHOD=FILE"),
            ("gap-tv=x.pth", "not a learned method"),
            ("hdnet=x.pth", "does not include hdnet"),
        ] {
            let e = parse_weight_flags(&[flag.into()], &methods)
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{flag}: {e}");
        }
        let e = parse_weight_flags(&["mst-s=a".into(), "mst-s=b".into()], &methods)
            .unwrap_err()
            .to_string();
        assert!(e.contains("twice"), "{e}");
    }
}
