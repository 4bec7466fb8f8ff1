//! ROS 2 names: node names, namespaces, and topic names resolved the ROS way.
//!
//! - `/a/b` is absolute;
//! - `b` is relative to the node's namespace (`/ns/b`);
//! - `~/b` is private to the node (`/ns/node/b`), `~` the node itself.
//!
//! Tokens are `[A-Za-z_][A-Za-z0-9_]*`, separated by single `/`; no trailing `/`. A name is
//! at most [`MAX_NAME_CHARS`] characters, as ROS 2 allows.

/// Longest name, node or topic, resolved (ROS 2's `RMW_TOPIC_MAX_NAME_LENGTH`).
pub const MAX_NAME_CHARS: usize = 255;

/// A malformed name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{what} {}: {why}", chronotope_yaml::quote(.name))]
pub struct NameError {
    /// What the name is (`node name`, `namespace`, `topic`).
    pub what: &'static str,
    /// The name as given.
    pub name: String,
    /// What is wrong with it.
    pub why: &'static str,
}

fn check_tokens(what: &'static str, name: &str, tokens: &str) -> Result<(), NameError> {
    let err = |why| NameError {
        what,
        name: name.to_owned(),
        why,
    };
    if name.len() > MAX_NAME_CHARS {
        return Err(err("longer than the 255 characters ROS 2 allows a name"));
    }
    if tokens.is_empty() {
        return Ok(());
    }
    for t in tokens.split('/') {
        let mut chars = t.chars();
        match chars.next() {
            None => return Err(err("empty token (a doubled or trailing '/')")),
            Some(c) if c.is_ascii_digit() => return Err(err("a token starts with a digit")),
            Some(c) if !(c.is_ascii_alphanumeric() || c == '_') => {
                return Err(err("only letters, digits and '_' are allowed in a token"))
            }
            _ => {}
        }
        if !chars.all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(err("only letters, digits and '_' are allowed in a token"));
        }
    }
    Ok(())
}

/// A namespace made absolute: `""` and `"/"` are `/`, `cell` is `/cell`.
///
/// # Errors
/// A malformed namespace.
pub fn namespace(ns: &str) -> Result<String, NameError> {
    let body = ns.trim_start_matches('/');
    check_tokens("namespace", ns, body)?;
    Ok(format!("/{body}"))
}

/// The fully qualified name of node `name` in namespace `ns` (`/ns/name`).
///
/// # Errors
/// A malformed namespace or a node name that is not a single token.
pub fn node_fqn(ns: &str, name: &str) -> Result<String, NameError> {
    let ns = namespace(ns)?;
    if name.is_empty() || name.contains('/') {
        return Err(NameError {
            what: "node name",
            name: name.to_owned(),
            why: "must be one token, without '/'",
        });
    }
    check_tokens("node name", name, name)?;
    let fqn = join(&ns, name);
    if fqn.len() > MAX_NAME_CHARS {
        return Err(NameError {
            what: "node name",
            name: fqn,
            why: "longer than the 255 characters ROS 2 allows a name, with its namespace",
        });
    }
    Ok(fqn)
}

fn join(ns: &str, rest: &str) -> String {
    if ns == "/" {
        format!("/{rest}")
    } else {
        format!("{ns}/{rest}")
    }
}

/// Resolves `topic` for node `node_fqn` (its namespace is everything before its last `/`).
///
/// # Errors
/// A malformed topic name.
pub fn resolve_topic(topic: &str, node_fqn: &str) -> Result<String, NameError> {
    let ns = match node_fqn.rfind('/') {
        Some(0) | None => "/",
        Some(i) => &node_fqn[..i],
    };
    let resolved = if topic == "~" {
        node_fqn.to_owned()
    } else if let Some(rest) = topic.strip_prefix("~/") {
        if rest.is_empty() {
            return Err(NameError {
                what: "topic",
                name: topic.to_owned(),
                why: "nothing after '~/'",
            });
        }
        check_tokens("topic", topic, rest)?;
        join(node_fqn, rest)
    } else if let Some(rest) = topic.strip_prefix('/') {
        check_tokens("topic", topic, rest)?;
        if rest.is_empty() {
            return Err(NameError {
                what: "topic",
                name: topic.to_owned(),
                why: "'/' alone is not a topic",
            });
        }
        topic.to_owned()
    } else {
        if topic.is_empty() {
            return Err(NameError {
                what: "topic",
                name: String::new(),
                why: "empty",
            });
        }
        check_tokens("topic", topic, topic)?;
        join(ns, topic)
    };
    if resolved.len() > MAX_NAME_CHARS {
        return Err(NameError {
            what: "topic",
            name: topic.to_owned(),
            why: "longer than the 255 characters ROS 2 allows a name, once resolved",
        });
    }
    Ok(resolved)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_resolve_the_ros_way() {
        assert_eq!(node_fqn("", "mesher").unwrap(), "/mesher");
        assert_eq!(node_fqn("/cell", "mesher").unwrap(), "/cell/mesher");
        assert_eq!(
            resolve_topic("~/slabs", "/cell/mesher").unwrap(),
            "/cell/mesher/slabs"
        );
        assert_eq!(
            resolve_topic("slabs", "/cell/mesher").unwrap(),
            "/cell/slabs"
        );
        assert_eq!(resolve_topic("slabs", "/mesher").unwrap(), "/slabs");
        assert_eq!(
            resolve_topic("/a/occupancy", "/cell/mesher").unwrap(),
            "/a/occupancy"
        );
        assert_eq!(resolve_topic("~", "/m").unwrap(), "/m");
        for bad in ["", "/", "a//b", "a/", "1a", "a b", "~/", "/a/"] {
            assert!(resolve_topic(bad, "/m").is_err(), "{bad:?}");
        }
        assert!(node_fqn("/", "a/b").is_err());
        assert!(node_fqn("/", "").is_err());
        assert!(namespace("a//b").is_err());
        let long = "a".repeat(300);
        let e = resolve_topic(&long, "/m").unwrap_err().to_string();
        assert!(e.contains("255") && e.len() < 120, "{e}");
        assert!(node_fqn(&"n".repeat(200), &"m".repeat(60)).is_err());
    }
}
