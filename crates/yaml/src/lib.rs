//! Bounded YAML loading for the files a user hands the suite: launch configs and sampler
//! scene files.
//!
//! serde_yaml_ng parses any YAML, however it is shaped, and some shapes are slow or costly:
//! deeply nested collections (`[[[[...`) take time that grows with the square of the file's
//! size, and aliases can expand a small file into a huge value. So the text is first read
//! by a linear pre-scan ([`prescan`]) that refuses, by the limit's name and value, before
//! anything is parsed:
//!
//! | limit            | value     | what it bounds                                        |
//! |------------------|-----------|-------------------------------------------------------|
//! | `config_bytes`   | 1 MiB     | the file's size (read at most this many bytes)        |
//! | `config_depth`   | 32        | nesting of collections (block indentation and `[`/`{`)|
//! | `config_entries` | 100 000   | lines, sequence items and flow entries                |
//! | aliases          | none      | `*name` is refused: write the value out               |
//!
//! Accepted text therefore parses in time linear in its size (a few tens of milliseconds for
//! 1 MiB) and into at most `config_entries` values (about 15 MB of parsed values).
//!
//! The pre-scan is conservative, not a YAML parser: it follows quotes, comments, block
//! scalars and flow collections well enough to measure depth and size; serde_yaml_ng then
//! reports the syntax errors. Messages quoting a user's text shorten it ([`quote`],
//! [`shorten`]) so that a 300-digit literal or a megabyte of name is never echoed.
#![warn(missing_docs)]

use std::io::Read;
use std::path::Path;

/// The bounds a YAML text must keep before it is parsed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct YamlLimits {
    /// Most bytes (`config_bytes`).
    pub max_bytes: usize,
    /// Deepest nesting of collections (`config_depth`).
    pub max_depth: usize,
    /// Most entries: block lines, sequence items, flow collections and flow entries
    /// (`config_entries`).
    pub max_entries: usize,
}

/// The limits of launch configs and scene files.
pub const CONFIG_LIMITS: YamlLimits = YamlLimits {
    max_bytes: 1 << 20,
    max_depth: 32,
    max_entries: 100_000,
};

/// What the pre-scan measured.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct YamlStats {
    /// Bytes.
    pub bytes: usize,
    /// Deepest nesting seen.
    pub depth: usize,
    /// Entries counted.
    pub entries: usize,
}

/// Why a YAML text is refused.
#[derive(Debug, thiserror::Error)]
pub enum YamlError {
    /// The file cannot be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not a regular file (a FIFO or a device may block or never end).
    #[error("{path}: not a regular file (a FIFO, socket or device could block or never end); give a file")]
    NotAFile {
        /// The path.
        path: String,
    },
    /// Over `config_bytes`.
    #[error("more than {limit} bytes; limit config_bytes = {limit} (1 MiB)")]
    TooLarge {
        /// The limit.
        limit: usize,
    },
    /// Over `config_depth`.
    #[error("line {line}: collections nested {depth} deep; limit config_depth = {limit}")]
    TooDeep {
        /// 1-based line.
        line: usize,
        /// The depth reached.
        depth: usize,
        /// The limit.
        limit: usize,
    },
    /// Over `config_entries`.
    #[error("line {line}: more than {limit} entries (lines, list items, values); limit config_entries = {limit}")]
    TooManyEntries {
        /// 1-based line where the limit was passed.
        line: usize,
        /// The limit.
        limit: usize,
    },
    /// An alias (`*name`).
    #[error("line {line}: alias {name}: aliases are not supported here (they can expand a small file into a huge one); write the value out")]
    Alias {
        /// 1-based line.
        line: usize,
        /// The alias as written (shortened).
        name: String,
    },
    /// serde_yaml_ng's error (long values quoted in it shortened).
    #[error("{0}")]
    Parse(String),
}

/// At most this many characters of a user's value are quoted in a message.
pub const QUOTE_CHARS: usize = 32;

/// `s` as quoted in a message: its first [`QUOTE_CHARS`] characters, then `…` if cut, in
/// double quotes with control characters escaped.
///
/// ```
/// assert_eq!(chronotope_yaml::quote("mesher"), "\"mesher\"");
/// assert_eq!(chronotope_yaml::quote(&"9".repeat(300)).chars().count(), 35);
/// ```
pub fn quote(s: &str) -> String {
    format!("\"{}\"", cut(s))
}

/// `s` cut to [`QUOTE_CHARS`] characters (then `…`), control characters escaped, unquoted.
pub fn cut(s: &str) -> String {
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i == QUOTE_CHARS {
            out.push('…');
            break;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// A number as a message shows it: plain when short, in exponent form when huge or tiny
/// (`1e300`, never three hundred digits), `.nan`/`.inf` as YAML writes them.
pub fn number(v: f64) -> String {
    if v.is_nan() {
        ".nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { ".inf" } else { "-.inf" }.into()
    } else if v == 0.0 || (1e-4..1e9).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// A message with every long word (a run of more than 40 characters without a space)
/// shortened to [`QUOTE_CHARS`] characters and `…`, and the whole cut at 400 characters:
/// for messages from serde_yaml_ng that quote the user's text in full.
pub fn shorten(msg: &str) -> String {
    let mut out = String::new();
    for (i, word) in msg.split(' ').enumerate() {
        if i > 0 {
            out.push(' ');
        }
        if word.chars().count() > 40 {
            let mut w = cut(word);
            // Keep a closing quote or backtick so the message still reads.
            if let Some(last) = word
                .chars()
                .last()
                .filter(|c| matches!(c, '"' | '`' | '\''))
            {
                w.push(last);
            }
            out.push_str(&w);
        } else {
            out.push_str(word);
        }
        if out.chars().count() > 400 {
            let cut: String = out.chars().take(400).collect();
            return cut + "…";
        }
    }
    out
}

/// Reads `path` whole if it is a regular file of at most `limits.max_bytes` bytes (never
/// more than that is read, whatever the file claims).
///
/// # Errors
/// [`YamlError::Io`], [`YamlError::NotAFile`], [`YamlError::TooLarge`], or `Io` for text
/// that is not UTF-8.
pub fn read_text(path: &Path, limits: &YamlLimits) -> Result<String, YamlError> {
    let shown = path.display().to_string();
    let io = |source| YamlError::Io {
        path: shown.clone(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(YamlError::NotAFile { path: shown });
    }
    if meta.len() > limits.max_bytes as u64 {
        return Err(YamlError::TooLarge {
            limit: limits.max_bytes,
        });
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .map_err(io)?
        .take(limits.max_bytes as u64 + 1)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() > limits.max_bytes {
        return Err(YamlError::TooLarge {
            limit: limits.max_bytes,
        });
    }
    String::from_utf8(bytes).map_err(|e| {
        io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        ))
    })
}

/// Checks `text` against `limits` and parses it as `T`.
///
/// # Errors
/// A limit passed ([`prescan`]), or [`YamlError::Parse`] with serde_yaml_ng's reason.
pub fn from_str<T: serde::de::DeserializeOwned>(
    text: &str,
    limits: &YamlLimits,
) -> Result<T, YamlError> {
    prescan(text, limits)?;
    serde_yaml_ng::from_str(text).map_err(|e| YamlError::Parse(shorten(&e.to_string())))
}

/// A linear pass over `text` that measures its size, nesting and entries, and refuses
/// aliases, before any parsing.
///
/// # Errors
/// [`YamlError::TooLarge`], [`YamlError::TooDeep`], [`YamlError::TooManyEntries`],
/// [`YamlError::Alias`].
pub fn prescan(text: &str, limits: &YamlLimits) -> Result<YamlStats, YamlError> {
    if text.len() > limits.max_bytes {
        return Err(YamlError::TooLarge {
            limit: limits.max_bytes,
        });
    }
    let mut s = Scan {
        limits: *limits,
        stats: YamlStats {
            bytes: text.len(),
            ..YamlStats::default()
        },
        line: 0,
        indents: Vec::new(),
        flow: 0,
        flow_base: 0,
        quote: None,
        block_scalar: None,
    };
    for (i, line) in text.lines().enumerate() {
        s.line = i + 1;
        s.scan_line(line)?;
    }
    Ok(s.stats)
}

struct Scan {
    limits: YamlLimits,
    stats: YamlStats,
    line: usize,
    /// Indentation columns of the open block collections.
    indents: Vec<usize>,
    /// Open flow collections.
    flow: usize,
    /// Block depth where the open flow collections started.
    flow_base: usize,
    /// Inside a quoted scalar: its quote character.
    quote: Option<u8>,
    /// Inside a block scalar (`|`, `>`): the indentation of the line that started it.
    block_scalar: Option<usize>,
}

impl Scan {
    fn entry(&mut self) -> Result<(), YamlError> {
        self.stats.entries += 1;
        if self.stats.entries > self.limits.max_entries {
            return Err(YamlError::TooManyEntries {
                line: self.line,
                limit: self.limits.max_entries,
            });
        }
        Ok(())
    }

    fn depth(&mut self, depth: usize) -> Result<(), YamlError> {
        self.stats.depth = self.stats.depth.max(depth);
        if depth > self.limits.max_depth {
            return Err(YamlError::TooDeep {
                line: self.line,
                depth,
                limit: self.limits.max_depth,
            });
        }
        Ok(())
    }

    fn scan_line(&mut self, line: &str) -> Result<(), YamlError> {
        let b = line.as_bytes();
        let indent = b.iter().take_while(|&&c| c == b' ').count();
        let blank = b[indent..]
            .iter()
            .all(|&c| c == b' ' || c == b'\t' || c == b'\r');
        if let Some(parent) = self.block_scalar {
            if blank || indent > parent {
                return Ok(());
            }
            self.block_scalar = None;
        }
        let mut i = 0;
        // Where a value may start (a flow collection, a quote, an alias, a block scalar).
        let mut value_start = true;
        let mut block_depth = self.flow_base;
        if self.quote.is_none() && self.flow == 0 {
            let rest = &b[indent..];
            if blank || rest.first() == Some(&b'#') || rest.first() == Some(&b'%') {
                return Ok(());
            }
            if rest.starts_with(b"---") || rest.starts_with(b"...") {
                self.indents.clear();
                i = indent + 3;
            } else {
                while self.indents.last().is_some_and(|&c| c > indent) {
                    self.indents.pop();
                }
                if self.indents.last() != Some(&indent) {
                    self.indents.push(indent);
                }
                i = indent;
            }
            self.entry()?;
            block_depth = self.indents.len();
            // `- - - x`: each dash opens a sequence on this line.
            while i < b.len() && b[i] == b'-' && (i + 1 == b.len() || b[i + 1] == b' ') {
                block_depth += 1;
                self.entry()?;
                i += 1;
                while i < b.len() && b[i] == b' ' {
                    i += 1;
                }
            }
            self.depth(block_depth)?;
        }
        while i < b.len() {
            let c = b[i];
            if let Some(q) = self.quote {
                if q == b'"' && c == b'\\' {
                    i += 2;
                    continue;
                }
                if c == q {
                    if q == b'\'' && b.get(i + 1) == Some(&b'\'') {
                        i += 2;
                        continue;
                    }
                    self.quote = None;
                    value_start = false;
                }
                i += 1;
                continue;
            }
            let after_space = i == 0 || matches!(b[i - 1], b' ' | b'\t');
            match c {
                b' ' | b'\t' | b'\r' => {}
                b'#' if after_space => return Ok(()),
                b'"' | b'\'' if value_start => self.quote = Some(c),
                b'*' if value_start => {
                    let end = b[i..]
                        .iter()
                        .position(|&c| matches!(c, b' ' | b',' | b']' | b'}'))
                        .map_or(b.len(), |p| i + p);
                    return Err(YamlError::Alias {
                        line: self.line,
                        name: cut(&line[i..end]),
                    });
                }
                b'[' | b'{' if value_start || self.flow > 0 => {
                    if self.flow == 0 {
                        self.flow_base = block_depth;
                    }
                    self.flow += 1;
                    self.entry()?;
                    self.depth(self.flow_base + self.flow)?;
                    value_start = true;
                }
                b']' | b'}' if self.flow > 0 => {
                    self.flow -= 1;
                    if self.flow == 0 {
                        self.flow_base = 0;
                    }
                    value_start = false;
                }
                b',' if self.flow > 0 => {
                    self.entry()?;
                    value_start = true;
                }
                b'|' | b'>' if value_start && self.flow == 0 => {
                    self.block_scalar = Some(indent);
                    return Ok(());
                }
                b':' | b'?' | b'-'
                    if b.get(i + 1).is_none_or(|&n| matches!(n, b' ' | b'\t'))
                        || (self.flow > 0 && c == b':') =>
                {
                    value_start = true;
                }
                _ => value_start = false,
            }
            i += 1;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(t: &str) -> Result<YamlStats, YamlError> {
        prescan(t, &CONFIG_LIMITS)
    }

    #[test]
    fn depth_is_measured_in_block_and_flow() {
        assert_eq!(scan("a: 1\nb: 2\n").unwrap().depth, 1);
        assert_eq!(scan("a:\n  b:\n    c: 1\n").unwrap().depth, 3);
        assert_eq!(scan("a: [1, [2, {b: 3}]]\n").unwrap().depth, 4);
        assert_eq!(scan("- - - x\n").unwrap().depth, 4);
        // Flow indicators inside quotes, comments and plain scalars are text.
        assert_eq!(
            scan("a: \"[[[[\"\nb: it's [x # [[[\nc: '[['\n")
                .unwrap()
                .depth,
            1
        );
        // A block scalar's lines are text, however indented.
        assert_eq!(
            scan("a: |\n  x\n      [[[[\n          y\nb: 1\n")
                .unwrap()
                .depth,
            1
        );
        let deep = format!("a: {}{}\n", "[".repeat(40), "]".repeat(40));
        assert!(matches!(
            scan(&deep),
            Err(YamlError::TooDeep { depth: 33, .. })
        ));
        let mut block = String::new();
        for i in 0..40 {
            block += &format!("{}k:\n", " ".repeat(i));
        }
        assert!(matches!(scan(&block), Err(YamlError::TooDeep { .. })));
    }

    #[test]
    fn aliases_and_size_are_refused_by_name() {
        let e = scan("a: &x [1]\nb: *x\n").unwrap_err().to_string();
        assert!(e.contains("alias *x") && e.contains("line 2"), "{e}");
        assert!(scan("a: x*y\nb: '*'\n").is_ok());
        let big = "a".repeat((1 << 20) + 1);
        assert!(scan(&big).unwrap_err().to_string().contains("config_bytes"));
        let many = "- 1\n".repeat(100_001);
        assert!(scan(&many)
            .unwrap_err()
            .to_string()
            .contains("config_entries = 100000"));
    }

    #[test]
    fn user_text_is_shortened() {
        assert_eq!(number(1e300), "1e300");
        assert_eq!(number(0.25), "0.25");
        assert_eq!(number(f64::NAN), ".nan");
        let m = shorten(&format!(
            "invalid value: \"{}\", expected x",
            "9".repeat(300)
        ));
        assert!(m.len() < 80 && m.ends_with("expected x"), "{m}");
        assert_eq!(cut("a\nb"), "a\\nb");
    }
}
