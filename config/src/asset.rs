//! Assets: the axes a laboratory calibrates, named by an id every survey
//! of the axis carries (`[asset] id`, `--asset`). A leaf: the configuration
//! and the survey records both name assets.

/// The asset of a survey whose asset is not known: imports without
/// `--asset`, configurations without `[asset] id`, surveys stored before
/// assets existed (other than simulated ones).
pub const UNASSIGNED: &str = "unassigned";

/// The asset of a survey on the simulated bench of `preset`: `sim-<preset>`.
pub fn simulated_asset(preset: &str) -> String {
    format!("sim-{preset}")
}

/// Check an asset id: 1-64 characters of letters, digits and `-_./`, in
/// canonical form: `/`-separated segments, none empty (no leading, trailing
/// or doubled `/`) and none `.` or `..` (an id is a name, and a page's path:
/// a proxy that normalises `..` or `a//b` would point elsewhere).
pub fn asset_id(text: &str) -> Result<String, String> {
    let bad = text.chars().find(|c| !(c.is_ascii_alphanumeric() || "-_./".contains(*c)));
    match (text.chars().count(), bad) {
        (0, _) => Err("an asset id cannot be empty".into()),
        (n, _) if n > 64 => Err(format!("the asset id '{text}' is {n} characters long (at most 64)")),
        (_, Some(c)) => Err(format!("the asset id '{text}' holds '{c}': only letters, digits and - _ . / are allowed")),
        _ => match text.split('/').find(|s| s.is_empty() || *s == "." || *s == "..") {
            Some("") => Err(format!(
                "the asset id '{text}' has an empty segment: no leading, trailing or doubled '/' (write it as '{}')",
                text.split('/').filter(|s| !s.is_empty()).collect::<Vec<_>>().join("/")
            )),
            Some(dots) => Err(format!("the asset id '{text}' has a segment '{dots}': '.' and '..' are not names")),
            None => Ok(text.to_string()),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn asset_ids_are_checked() {
        assert_eq!(asset_id("lab-2/az.axis_1").unwrap(), "lab-2/az.axis_1");
        assert!(asset_id("").is_err() && asset_id(&"a".repeat(65)).is_err() && asset_id(&"a".repeat(64)).is_ok());
        let e = asset_id("bay 3").unwrap_err();
        assert!(e.contains("' '"), "{e}");
        for (bad, says) in [
            ("..", "segment '..'"),
            ("../../etc", "segment '..'"),
            ("a/./b", "segment '.'"),
            ("/leading", "empty segment"),
            ("trailing/", "empty segment"),
            ("a//b", "write it as 'a/b'"),
        ] {
            let e = asset_id(bad).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
        assert!(asset_id("a.b/c..d").is_ok(), "dots inside a name are a name's");
        assert_eq!(simulated_asset("fig8"), "sim-fig8");
    }
}
