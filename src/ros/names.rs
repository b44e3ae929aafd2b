//! ROS 2 name resolution: relative names, `~`, the node namespace and remaps.
//!
//! Why here and not in ros2-client: ros2-client 0.12.1 turns a relative name in the root namespace
//! into `rt//imu`, which no ROS peer meets, and it applies no remaps. The node therefore resolves
//! every name itself, by the ROS 2 rules (design article "Topic and Service name mapping to DDS",
//! REP-144 name syntax), and hands ros2-client absolute names only.

/// A name that breaks the ROS 2 name syntax.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum NameError {
    /// The name (or namespace) is not valid ROS 2 syntax.
    #[error("invalid ROS name '{name}': {reason}")]
    Invalid {
        /// The offending name.
        name: String,
        /// Which rule it breaks.
        reason: &'static str,
    },
}

/// Checks a node base name: `[A-Za-z_][A-Za-z0-9_]*`.
///
/// # Errors
/// [`NameError::Invalid`] naming the rule broken.
pub fn check_node_name(name: &str) -> Result<(), NameError> {
    let bad = |reason| {
        Err(NameError::Invalid {
            name: name.to_string(),
            reason,
        })
    };
    let mut chars = name.chars();
    match chars.next() {
        None => bad("empty"),
        Some(c) if !(c.is_ascii_alphabetic() || c == '_') => bad("must start with a letter or '_'"),
        _ if !chars.all(|c| c.is_ascii_alphanumeric() || c == '_') => {
            bad("only letters, digits and '_' are allowed")
        }
        _ => Ok(()),
    }
}

/// Normalises a namespace to an absolute one without a trailing slash (`/` for the root).
///
/// # Errors
/// [`NameError::Invalid`] when a token is not valid.
pub fn normalise_namespace(ns: &str) -> Result<String, NameError> {
    let trimmed = ns.trim_end_matches('/');
    if trimmed.is_empty() {
        return Ok("/".to_string());
    }
    let abs = if trimmed.starts_with('/') {
        trimmed.to_string()
    } else {
        format!("/{trimmed}")
    };
    check_absolute(&abs)?;
    Ok(abs)
}

/// Expands `name` to an absolute name in the node's namespace (no remaps).
///
/// # Formula
/// ```text
/// "/a/b"   → "/a/b"                 (absolute: unchanged)
/// "~"      → ns/node
/// "~/a"    → ns/node/a              (private)
/// "a/b"    → ns/a/b                 (relative)
/// ```
/// where ns is the node namespace ("/" gives "/node", "/a", never "//a").
///
/// # Errors
/// [`NameError::Invalid`] for empty names, `~x` without a slash, `//`, bad characters, or tokens
/// that start with a digit.
pub fn expand(name: &str, namespace: &str, node: &str) -> Result<String, NameError> {
    let join = |base: &str, rest: &str| {
        if rest.is_empty() {
            base.to_string()
        } else if base == "/" {
            format!("/{rest}")
        } else {
            format!("{base}/{rest}")
        }
    };
    if name.is_empty() {
        return Err(NameError::Invalid {
            name: String::new(),
            reason: "empty",
        });
    }
    let full = if name.starts_with('/') {
        name.to_string()
    } else if let Some(rest) = name.strip_prefix('~') {
        let private = join(namespace, node);
        match rest.strip_prefix('/') {
            Some(rest) => join(&private, rest),
            None if rest.is_empty() => private,
            None => {
                return Err(NameError::Invalid {
                    name: name.to_string(),
                    reason: "'~' must be followed by '/'",
                })
            }
        }
    } else {
        join(namespace, name)
    };
    check_absolute(&full).map_err(|_| NameError::Invalid {
        name: name.to_string(),
        reason: "tokens are [A-Za-z_][A-Za-z0-9_]* separated by single '/', no trailing '/'",
    })?;
    Ok(full)
}

/// Resolves `name` the ROS 2 way: expand it, then apply the first remap whose expanded `from`
/// equals it.
///
/// `remaps` are (from, to) pairs as given on the command line; both sides are expanded in the
/// node's namespace, so `-r imu:=/sensors/imu` and `-r /ns/imu:=/sensors/imu` both work.
///
/// # Errors
/// [`NameError::Invalid`] when the name or the chosen remap target is not valid.
pub fn resolve(
    name: &str,
    namespace: &str,
    node: &str,
    remaps: &[(String, String)],
) -> Result<String, NameError> {
    let full = expand(name, namespace, node)?;
    for (from, to) in remaps {
        if expand(from, namespace, node).is_ok_and(|f| f == full) {
            return expand(to, namespace, node);
        }
    }
    Ok(full)
}

fn check_absolute(name: &str) -> Result<(), NameError> {
    let bad = |reason| {
        Err(NameError::Invalid {
            name: name.to_string(),
            reason,
        })
    };
    let Some(body) = name.strip_prefix('/') else {
        return bad("not absolute");
    };
    if body.is_empty() {
        return Ok(());
    }
    for token in body.split('/') {
        let mut chars = token.chars();
        match chars.next() {
            None => return bad("empty token ('//' or trailing '/')"),
            Some(c) if c.is_ascii_digit() => return bad("a token must not start with a digit"),
            Some(c) if !(c.is_ascii_alphanumeric() || c == '_') => return bad("bad character"),
            _ => {}
        }
        if !chars.all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return bad("bad character");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_private_and_absolute_names_expand_by_ros_rules() {
        assert_eq!(expand("imu", "/", "fdavar").unwrap(), "/imu");
        assert_eq!(expand("imu", "/robot", "fdavar").unwrap(), "/robot/imu");
        assert_eq!(expand("/imu", "/robot", "fdavar").unwrap(), "/imu");
        assert_eq!(
            expand("~/gyro_x/state", "/", "fdavar").unwrap(),
            "/fdavar/gyro_x/state"
        );
        assert_eq!(
            expand("~/gyro_x/state", "/r", "f").unwrap(),
            "/r/f/gyro_x/state"
        );
        assert_eq!(expand("~", "/r", "f").unwrap(), "/r/f");
    }

    #[test]
    fn root_namespace_never_gives_a_double_slash() {
        // The ros2-client bug (`rt//imu`) this module exists for.
        for name in ["imu", "~/x", "a/b"] {
            assert!(!expand(name, "/", "n").unwrap().contains("//"), "{name}");
        }
    }

    #[test]
    fn invalid_names_are_refused_with_a_reason() {
        fn reason<T: std::fmt::Debug>(r: Result<T, NameError>) -> &'static str {
            match r {
                Err(NameError::Invalid { reason, .. }) => reason,
                Ok(v) => panic!("accepted: {v:?}"),
            }
        }
        let syntax = "tokens are [A-Za-z_][A-Za-z0-9_]* separated by single '/', no trailing '/'";
        for (bad, why) in [
            ("", "empty"),
            ("~x", "'~' must be followed by '/'"),
            ("a//b", syntax),
            ("a/", syntax),
            ("1imu", syntax),
            ("im-u", syntax),
            ("/a/2b", syntax),
        ] {
            assert_eq!(reason(expand(bad, "/", "n")), why, "{bad:?}");
        }
        assert!(check_node_name("fdavar").is_ok());
        assert_eq!(reason(check_node_name("")), "empty");
        assert_eq!(reason(check_node_name("9x")), "must start with a letter or '_'");
        assert_eq!(reason(check_node_name("a/b")), "only letters, digits and '_' are allowed");
    }

    #[test]
    fn remaps_match_after_expansion() {
        let remaps = vec![("imu".to_string(), "/sensors/imu".to_string())];
        assert_eq!(resolve("imu", "/r", "f", &remaps).unwrap(), "/sensors/imu");
        assert_eq!(
            resolve("/r/imu", "/r", "f", &remaps).unwrap(),
            "/sensors/imu"
        );
        assert_eq!(resolve("/imu", "/r", "f", &remaps).unwrap(), "/imu");
        let private = vec![("~/gyro_x/state".to_string(), "gx".to_string())];
        assert_eq!(
            resolve("~/gyro_x/state", "/r", "f", &private).unwrap(),
            "/r/gx"
        );
    }

    #[test]
    fn namespaces_are_normalised() {
        assert_eq!(normalise_namespace("").unwrap(), "/");
        assert_eq!(normalise_namespace("/").unwrap(), "/");
        assert_eq!(normalise_namespace("robot/").unwrap(), "/robot");
        assert_eq!(normalise_namespace("/a/b").unwrap(), "/a/b");
        assert!(normalise_namespace("/a//b").is_err());
    }
}
