//! The learned methods a study can run, where their official weights come
//! from, and finding a weights file for each (a per-method file, or a
//! folder searched by conventional names).

use std::path::{Path, PathBuf};

use anyhow::bail;
use cassi_core::recon::MethodId;
use cassi_core::recon::registry::learned_names;

/// True when this build can run the learned methods (feature `nets`).
pub const NETS_BUILT: bool = cfg!(feature = "nets");

/// Where a user gets the official weights of `method` (the registry's hint).
pub fn official_weights(method: MethodId) -> &'static str {
    method
        .spec()
        .weights
        .map_or("none: it takes no weights", |hint| hint.official)
}

/// The weights file of learned method `method`: the one given for it in
/// `given` (`--weights METHOD=FILE`), else the first of
/// [`MethodId::weight_file_names`] in `dir` (`--weights-dir`). Errors say what was
/// tried and where official weights come from.
pub fn resolve_weights(
    method: MethodId,
    given: &[(MethodId, PathBuf)],
    dir: Option<&Path>,
) -> anyhow::Result<PathBuf> {
    if let Some((_, path)) = given.iter().find(|(m, _)| *m == method) {
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
    let names = method.weight_file_names();
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
/// `methods` are the names given to `--methods` (not checked here: an
/// unknown one is reported where the study's methods are parsed).
pub fn parse_weight_flags(
    flags: &[String],
    methods: &[String],
) -> anyhow::Result<Vec<(MethodId, PathBuf)>> {
    let mut out: Vec<(MethodId, PathBuf)> = Vec::new();
    for flag in flags {
        let Some((name, path)) = flag.split_once('=') else {
            bail!("--weights {flag}: expected METHOD=FILE, e.g. --weights mst-s=mst_s.pth");
        };
        let name = name.trim();
        let Some(method) = MethodId::parse(name).ok().filter(|m| m.kind().is_learned()) else {
            bail!(
                "--weights {flag}: '{name}' is not a learned method (known: {})",
                learned_names().collect::<Vec<_>>().join(", ")
            );
        };
        if !methods
            .iter()
            .any(|m| MethodId::parse(m).ok() == Some(method))
        {
            bail!("--weights {flag}: --methods does not include {method}");
        }
        if out.iter().any(|(m, _)| *m == method) {
            bail!("--weights: {method} is given twice");
        }
        out.push((method, PathBuf::from(path)));
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
            resolve_weights(MethodId::MstS, &[], Some(&dir)).unwrap(),
            dir.join("mst_s.pth")
        );
        assert_eq!(
            resolve_weights(MethodId::PnpHsicnn, &[], Some(&dir)).unwrap(),
            dir.join("deep_denoiser.pth")
        );
        let e = resolve_weights(MethodId::HdNet, &[], Some(&dir))
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
        let given = vec![(MethodId::MstS, own.clone())];
        assert_eq!(
            resolve_weights(MethodId::MstS, &given, Some(&dir)).unwrap(),
            own
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn missing_weights_say_where_official_ones_come_from() {
        let e = resolve_weights(MethodId::PnpHsicnn, &[], None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--weights pnp-hsicnn=FILE") && e.contains("zsm1211/PnP-CASSI"),
            "{e}"
        );
        let given = vec![(MethodId::MstL, PathBuf::from("/nonexistent/mst_l.pth"))];
        let e = resolve_weights(MethodId::MstL, &given, None)
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
        assert_eq!(ok, vec![(MethodId::MstS, PathBuf::from("a/b.pth"))]);
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
