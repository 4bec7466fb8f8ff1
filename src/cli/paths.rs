//! The paths a command reads and writes, checked against each other before anything is opened
//! for writing, so that an output can never destroy an input or a recording.
//!
//! Every output is compared by identity (the same device and inode, after links) and by place
//! (inside an input bag's directory, or holding one) with every input and with every other
//! output, and refused by name on a match. An output path that already holds a bag (an MCAP
//! or SQLite file, a zstd-compressed one, or a rosbag2 directory) is refused unless the user
//! asked to replace it (`--overwrite`), or unless it is a bag this program derived (`replay`,
//! `scene`, `sample`: made again from its inputs, so replaced by the next run) and the new
//! output is a bag too. A directory is replaced only when it holds nothing but a bag.
//! Special files (FIFOs, devices, sockets) are refused as outputs. The writing itself is
//! atomic and never follows a link (`crate::fsio`).

use std::path::{Component, Path, PathBuf};

use super::CliError;
use crate::bag::{is_directory_path, METADATA_FILE};
use crate::fsio::{FileId, SpecialKind};

/// What an output is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputKind {
    /// A file (a report, a summary, a picture).
    File,
    /// A bag: an MCAP file, or a rosbag2 directory if the path ends with `/` or is one.
    /// `derived` says whether this command derives it from its inputs (it may then replace
    /// a bag derived so, without `--overwrite`).
    Bag {
        /// The command derives the bag (replay, scene, sample), as opposed to recording it.
        derived: bool,
    },
    /// A directory whose files the command writes (PLY slices).
    Dir,
}

/// What to do about an output path that holds a bag the user did not ask to replace.
const GIVE_ANOTHER: &str = "give another path, or pass --overwrite to replace it";

/// Why an output path is refused ([`CliError::Output`]), and what to do.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum OutputRefusal {
    /// A special file (a FIFO, a device, a socket).
    #[error("it is {0}; an output must be a regular file or a new path")]
    Special(SpecialKind),
    /// The same file as an input.
    #[error("it is {role} ({}), the same file; write the output elsewhere", path.display())]
    IsInput {
        /// What the input is ("the input bag").
        role: String,
        /// The input's path.
        path: PathBuf,
    },
    /// A place inside an input directory.
    #[error(
        "it lies inside {role} ({}): writing there would change the recording; write the \
         output elsewhere",
        path.display()
    )]
    InsideInput {
        /// What the input is ("the input bag's directory").
        role: String,
        /// The input's path.
        path: PathBuf,
    },
    /// A directory output that holds an input.
    #[error("it holds {role} ({}); write the output elsewhere", path.display())]
    HoldsInput {
        /// What the input is.
        role: String,
        /// The input's path.
        path: PathBuf,
    },
    /// The same place as another output, or one inside the other.
    #[error(
        "{option} names the same place ({}); give each output its own path",
        path.display()
    )]
    SamePlace {
        /// The other output's option.
        option: String,
        /// The other output's path.
        path: PathBuf,
    },
    /// A directory where a file is written.
    #[error("it is a directory; give a file name")]
    Directory,
    /// A directory holding files other than a bag, where a rosbag2 directory is written.
    #[error(
        "it is a directory holding other files; a rosbag2 output needs a new or an empty \
         directory"
    )]
    DirectoryNotEmpty,
    /// A rosbag2 directory that also holds other files (never replaced).
    #[error(
        "it is a rosbag2 directory that also holds other files ({}); it is not replaced even \
         with --overwrite: give another path",
        strays.join(", ")
    )]
    Strays {
        /// The first few other files.
        strays: Vec<String>,
    },
    /// A rosbag2 directory holding a bag this command did not derive.
    #[error(
        "it is a rosbag2 directory holding a bag this command did not derive (a recording, or \
         a bag of another program); {GIVE_ANOTHER}"
    )]
    HoldsRecordedDirectory,
    /// A file where a directory (a path ending with `/`) is written.
    #[error("it is a file, not a directory")]
    NotADirectory,
    /// A bag file the command may not replace without `--overwrite`.
    #[error(
        "it holds {} ({format}); {GIVE_ANOTHER}",
        if *derived {
            "a bag this program derived"
        } else {
            "a bag this command did not derive (a recording, or a bag of another program)"
        }
    )]
    HoldsBag {
        /// The bag's format ("MCAP", "SQLite", "zstd-compressed").
        format: &'static str,
        /// Whether this program derived it (it is then refused for another kind of output
        /// only).
        derived: bool,
    },
}

/// One path read.
#[derive(Debug, Clone)]
struct Input {
    /// What it is, for messages ("the input bag", "the launch config").
    role: String,
    path: PathBuf,
    id: Option<FileId>,
    /// The path with links resolved, for a directory (outputs must not lie inside it).
    dir: Option<PathBuf>,
}

/// One path written.
#[derive(Debug, Clone)]
struct Output {
    /// The option that names it (`--out`).
    role: String,
    path: PathBuf,
    kind: OutputKind,
}

/// The inputs and outputs of one command, checked with [`Paths::check`].
#[derive(Debug, Default)]
pub struct Paths {
    inputs: Vec<Input>,
    outputs: Vec<Output>,
    overwrite: bool,
}

impl Paths {
    /// No paths yet; `overwrite` is the user's `--overwrite`.
    pub fn new(overwrite: bool) -> Self {
        Self {
            overwrite,
            ..Self::default()
        }
    }

    /// A file read (a launch config, a scene file, an image).
    pub fn input(mut self, role: &str, path: &Path) -> Self {
        self.push_input(role, path);
        self
    }

    /// The bag read: a file, or a rosbag2 directory (its own files and the split files its
    /// metadata lists, wherever links lead them, count as inputs).
    pub fn bag(mut self, path: &Path) -> Self {
        self.push_input("the input bag", path);
        let dir = if path.is_dir() {
            Some(path.to_path_buf())
        } else if path.file_name().is_some_and(|n| n == METADATA_FILE) {
            Some(crate::fsio::parent_dir(path).to_path_buf())
        } else {
            None
        };
        if let Some(dir) = dir {
            self.push_input("the input bag's directory", &dir);
            if let Ok(entries) = std::fs::read_dir(&dir) {
                for e in entries.flatten().take(2 * crate::bag::MAX_SPLIT_FILES) {
                    self.push_input(
                        &format!("a file of the input bag {}", dir.display()),
                        &e.path(),
                    );
                }
            }
            if let Ok(info) = crate::bag::Rosbag2Dir::open(&dir) {
                for f in &info.files {
                    self.push_input(
                        &format!("a split file of the input bag {}", dir.display()),
                        f,
                    );
                }
            }
        }
        self
    }

    /// Inputs named by a launch config: the config itself and the files its nodes read
    /// (carving cut-out images).
    pub fn launch_config(
        mut self,
        path: &Path,
        config: Option<&crate::node::launch::LaunchConfig>,
    ) -> Self {
        self.push_input("the launch config", path);
        if let Some(c) = config {
            for f in c.input_files() {
                self.push_input("a file the launch config reads", &f);
            }
        }
        self
    }

    /// A path written, named by the option `role`.
    pub fn output(mut self, role: &str, path: Option<&Path>, kind: OutputKind) -> Self {
        if let Some(path) = path {
            self.outputs.push(Output {
                role: role.to_owned(),
                path: path.to_path_buf(),
                kind,
            });
        }
        self
    }

    fn push_input(&mut self, role: &str, path: &Path) {
        let meta = std::fs::metadata(path).ok();
        self.inputs.push(Input {
            role: role.to_owned(),
            path: path.to_path_buf(),
            id: meta.as_ref().map(FileId::of),
            dir: meta
                .filter(|m| m.is_dir())
                .and_then(|_| path.canonicalize().ok()),
        });
    }

    /// Checks every output against every input, every other output and what it already
    /// holds (see the module documentation).
    ///
    /// # Errors
    /// [`CliError::Output`] naming the output, the option and why.
    pub fn check(&self) -> Result<(), CliError> {
        for (i, o) in self.outputs.iter().enumerate() {
            let refuse = |reason: OutputRefusal| CliError::Output {
                option: o.role.clone(),
                path: o.path.clone(),
                reason,
            };
            let meta = std::fs::metadata(&o.path).ok();
            let place = resolved(&o.path);
            if let Some(kind) = meta.as_ref().and_then(SpecialKind::of) {
                if kind != SpecialKind::Directory {
                    return Err(refuse(OutputRefusal::Special(kind)));
                }
            }
            let id = meta.as_ref().map(FileId::of);
            for input in &self.inputs {
                if id.is_some() && id == input.id {
                    return Err(refuse(OutputRefusal::IsInput {
                        role: input.role.clone(),
                        path: input.path.clone(),
                    }));
                }
                if let Some(dir) = &input.dir {
                    if place.starts_with(dir) {
                        return Err(refuse(OutputRefusal::InsideInput {
                            role: input.role.clone(),
                            path: input.path.clone(),
                        }));
                    }
                }
                if o.kind != OutputKind::File {
                    let inside = input
                        .dir
                        .clone()
                        .or_else(|| input.path.canonicalize().ok())
                        .is_some_and(|p| p.starts_with(&place));
                    if inside {
                        return Err(refuse(OutputRefusal::HoldsInput {
                            role: input.role.clone(),
                            path: input.path.clone(),
                        }));
                    }
                }
            }
            for other in &self.outputs[..i] {
                let other_place = resolved(&other.path);
                let same =
                    place == other_place || (id.is_some() && id == FileId::of_path(&other.path));
                let within = |a: &Output, a_place: &Path, b_place: &Path| {
                    a.kind != OutputKind::File && b_place.starts_with(a_place)
                };
                if same || within(o, &place, &other_place) || within(other, &other_place, &place) {
                    return Err(refuse(OutputRefusal::SamePlace {
                        option: other.role.clone(),
                        path: other.path.clone(),
                    }));
                }
            }
            if let Some(meta) = &meta {
                self.check_existing(o, meta).map_err(refuse)?;
            }
        }
        Ok(())
    }

    /// What an output path already holds, and whether it may be replaced.
    fn check_existing(&self, o: &Output, meta: &std::fs::Metadata) -> Result<(), OutputRefusal> {
        let as_dir = match o.kind {
            OutputKind::Bag { .. } => is_directory_path(&o.path),
            OutputKind::Dir => true,
            OutputKind::File => false,
        };
        if meta.is_dir() {
            if !as_dir {
                return Err(OutputRefusal::Directory);
            }
            if o.kind == OutputKind::Dir {
                return Ok(());
            }
            let entries = dir_entries(&o.path);
            if entries.is_empty() {
                return Ok(());
            }
            let holds_bag = entries.iter().any(|n| {
                n == METADATA_FILE || crate::bag::storage_file_name(n.to_string_lossy().as_ref())
            });
            if !holds_bag {
                return Err(OutputRefusal::DirectoryNotEmpty);
            }
            let strays: Vec<String> = entries
                .iter()
                .map(|n| n.to_string_lossy().into_owned())
                .filter(|n| n != METADATA_FILE && !crate::bag::storage_file_name(n))
                .take(3)
                .collect();
            if !strays.is_empty() {
                return Err(OutputRefusal::Strays { strays });
            }
            let derived = crate::bag::Rosbag2Dir::open(&o.path)
                .ok()
                .and_then(|d| d.derived_by)
                .is_some();
            if self.overwrite || (derived && matches!(o.kind, OutputKind::Bag { derived: true })) {
                return Ok(());
            }
            return Err(OutputRefusal::HoldsRecordedDirectory);
        }
        if as_dir && o.path.as_os_str().to_string_lossy().ends_with('/') {
            return Err(OutputRefusal::NotADirectory);
        }
        let Some(format) = bag_format(&o.path) else {
            // Any other file is replaced, whole and at once.
            return Ok(());
        };
        let derived = crate::bag::derived_by(&o.path).is_some();
        if self.overwrite || (derived && matches!(o.kind, OutputKind::Bag { derived: true })) {
            return Ok(());
        }
        Err(OutputRefusal::HoldsBag { format, derived })
    }
}

/// The format of a bag file at `path` by its first bytes, if it is one.
fn bag_format(path: &Path) -> Option<&'static str> {
    use std::io::Read;
    let mut head = [0u8; 16];
    let mut f = crate::fsio::open_regular(path).ok()?;
    let mut n = 0;
    while n < head.len() {
        match f.read(&mut head[n..]) {
            Ok(0) | Err(_) => break,
            Ok(k) => n += k,
        }
    }
    let head = &head[..n];
    if head.starts_with(b"\x89MCAP") {
        Some("MCAP")
    } else if head.starts_with(b"SQLite format 3\0") {
        Some("SQLite")
    } else if head.starts_with(&[0x28, 0xB5, 0x2F, 0xFD]) {
        Some("zstd-compressed")
    } else {
        None
    }
}

/// The names in a directory (at most a few thousand are looked at).
fn dir_entries(dir: &Path) -> Vec<std::ffi::OsString> {
    std::fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .take(2 * crate::bag::MAX_SPLIT_FILES)
                .map(|e| e.file_name())
                .collect()
        })
        .unwrap_or_default()
}

/// Where a path leads: its deepest existing ancestor with links resolved, then the rest as
/// written (`.` dropped, `..` applied), so that two spellings of one new file compare equal.
fn resolved(path: &Path) -> PathBuf {
    let absolute = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir()
            .unwrap_or_else(|_| PathBuf::from("/"))
            .join(path)
    };
    if let Ok(c) = absolute.canonicalize() {
        return c;
    }
    let mut rest: Vec<std::ffi::OsString> = Vec::new();
    let mut base = absolute.as_path();
    loop {
        if let Ok(c) = base.canonicalize() {
            let mut out = c;
            for part in rest.iter().rev() {
                out.push(part);
            }
            return normalise(&out);
        }
        match (base.parent(), base.file_name()) {
            (Some(parent), Some(name)) => {
                rest.push(name.to_owned());
                base = parent;
            }
            _ => return normalise(&absolute),
        }
    }
}

/// `path` with `.` dropped and `..` applied lexically.
fn normalise(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_mcap(path: &Path, derived: bool) {
        let mut o = crate::bag::BagWriteOptions::new();
        if derived {
            o = o.derived("replay");
        }
        crate::bag::BagWriter::create_with(path, o)
            .unwrap()
            .finish()
            .unwrap();
    }

    fn refused(p: &Paths) -> String {
        match p.check() {
            Err(e) => e.to_string(),
            Ok(()) => panic!("accepted"),
        }
    }

    #[test]
    fn an_output_that_is_the_input_is_refused_however_it_is_spelt() {
        let d = tempfile::tempdir().unwrap();
        let bag = d.path().join("in.mcap");
        write_mcap(&bag, false);
        std::os::unix::fs::symlink(&bag, d.path().join("link.mcap")).unwrap();
        std::fs::hard_link(&bag, d.path().join("hard.mcap")).unwrap();
        for out in ["in.mcap", "link.mcap", "hard.mcap", "./sub/../in.mcap"] {
            std::fs::create_dir_all(d.path().join("sub")).unwrap();
            let p = Paths::new(true).bag(&bag).output(
                "--out",
                Some(&d.path().join(out)),
                OutputKind::Bag { derived: true },
            );
            let e = refused(&p);
            assert!(
                e.contains("--out") && e.contains("the input bag"),
                "{out}: {e}"
            );
        }
        let p = Paths::new(true)
            .bag(&bag)
            .output("--report", Some(&bag), OutputKind::File);
        assert!(refused(&p).contains("the same file"));
    }

    #[test]
    fn outputs_in_or_over_an_input_directory_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let rec = d.path().join("rec");
        write_mcap(&rec.join(""), false);
        let p = Paths::new(true).bag(&rec).output(
            "--out",
            Some(&rec.join("")),
            OutputKind::Bag { derived: true },
        );
        assert!(refused(&p).contains("the input bag"));
        let p = Paths::new(true).bag(&rec).output(
            "--report",
            Some(&rec.join("report.json")),
            OutputKind::File,
        );
        assert!(refused(&p).contains("inside"));
        let p = Paths::new(true).bag(&rec).output(
            "--out",
            Some(&d.path().join("")),
            OutputKind::Bag { derived: true },
        );
        assert!(refused(&p).contains("holds"));
    }

    #[test]
    fn two_outputs_at_one_place_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let x = d.path().join("x");
        let p = Paths::new(false)
            .output("--report", Some(&x), OutputKind::File)
            .output("--out", Some(&x), OutputKind::Bag { derived: true });
        assert!(refused(&p).contains("--report names the same place"));
        let p = Paths::new(false)
            .output(
                "--out",
                Some(&d.path().join("o/")),
                OutputKind::Bag { derived: true },
            )
            .output(
                "--report",
                Some(&d.path().join("o/r.json")),
                OutputKind::File,
            );
        assert!(refused(&p).contains("same place"));
    }

    #[test]
    fn a_bag_not_derived_is_replaced_only_on_request() {
        let d = tempfile::tempdir().unwrap();
        let rec = d.path().join("rec.mcap");
        write_mcap(&rec, false);
        let ours = d.path().join("ours.mcap");
        write_mcap(&ours, true);
        let bag_out = OutputKind::Bag { derived: true };
        let e = refused(&Paths::new(false).output("--out", Some(&rec), bag_out));
        assert!(e.contains("--overwrite") && e.contains("MCAP"), "{e}");
        assert!(Paths::new(true)
            .output("--out", Some(&rec), bag_out)
            .check()
            .is_ok());
        // A derived bag is replaced by the next derived output, not by a report.
        assert!(Paths::new(false)
            .output("--out", Some(&ours), bag_out)
            .check()
            .is_ok());
        let e = refused(&Paths::new(false).output("--report", Some(&ours), OutputKind::File));
        assert!(e.contains("derived"), "{e}");
        // A recording is never replaced by a recorder without --overwrite.
        let e = refused(&Paths::new(false).output(
            "--out",
            Some(&ours),
            OutputKind::Bag { derived: false },
        ));
        assert!(e.contains("--overwrite"), "{e}");
        // Other files are replaced.
        std::fs::write(d.path().join("r.json"), b"{}").unwrap();
        assert!(Paths::new(false)
            .output("--report", Some(&d.path().join("r.json")), OutputKind::File)
            .check()
            .is_ok());
    }

    #[test]
    fn directories_are_replaced_only_when_they_hold_nothing_but_a_bag() {
        let d = tempfile::tempdir().unwrap();
        let bag_out = OutputKind::Bag { derived: true };
        let other = d.path().join("other/");
        std::fs::create_dir(&other).unwrap();
        std::fs::write(other.join("notes.txt"), b"x").unwrap();
        let e = refused(&Paths::new(true).output("--out", Some(&other), bag_out));
        assert!(e.contains("other files"), "{e}");
        let empty = d.path().join("empty/");
        std::fs::create_dir(&empty).unwrap();
        assert!(Paths::new(false)
            .output("--out", Some(&empty), bag_out)
            .check()
            .is_ok());
        let rec = d.path().join("rec/");
        write_mcap(&rec, false);
        let e = refused(&Paths::new(false).output("--out", Some(&rec), bag_out));
        assert!(e.contains("rosbag2 directory"), "{e}");
        assert!(Paths::new(true)
            .output("--out", Some(&rec), bag_out)
            .check()
            .is_ok());
        std::fs::write(rec.join("notes.txt"), b"x").unwrap();
        let e = refused(&Paths::new(true).output("--out", Some(&rec), bag_out));
        assert!(e.contains("notes.txt"), "{e}");
        let e = refused(&Paths::new(true).output("--report", Some(&empty), OutputKind::File));
        assert!(e.contains("is a directory"), "{e}");
    }
}
