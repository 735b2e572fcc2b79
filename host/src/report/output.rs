//! Writing result files: every output of a command at the end, or none. [`Outputs`] stages each
//! file as a temporary beside its destination and renames them all only when the command has
//! rendered and checked everything; on any failure (or when dropped uncommitted) the temporaries
//! are removed and no destination is touched. An output that names an input is refused. A
//! destination that is not a regular file (`/dev/null`, `/dev/stdout`, a named pipe) is written
//! into at the commit instead: a rename would put a file in the device's place.
use std::io::Write;
use std::path::{Path, PathBuf};

/// Why an output could not be staged or committed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    #[error("{path}: that is an input of this command; name another file", path = .path.display())]
    IsInput { path: PathBuf },
    #[error("{path}: named twice as an output of this command", path = .path.display())]
    Twice { path: PathBuf },
    #[error("writing {path}: {source}", path = .path.display())]
    Write { path: PathBuf, source: std::io::Error },
    #[error("writing {path}: the directory {dir} does not exist", path = .path.display(), dir = .dir.display())]
    NoDirectory { path: PathBuf, dir: PathBuf },
    #[error("{path}: that is a directory; name a file in it", path = .path.display())]
    IsDirectory { path: PathBuf },
    #[error("{path}: that is a file; name a directory for the pictures", path = .path.display())]
    NotADirectory { path: PathBuf },
}

impl OutputError {
    fn write(path: &Path, source: std::io::Error) -> Self {
        OutputError::Write { path: path.to_owned(), source }
    }
}

/// Whether two paths name the same file: the same canonical path, or (on Unix) the same
/// device and inode, so a hard link or a symbolic link to an input is caught too. A path that
/// does not exist names the same file as another only if both resolve to the same place.
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return ma.dev() == mb.dev() && ma.ino() == mb.ino();
        }
    }
    match (resolved(a), resolved(b)) {
        (Some(a), Some(b)) => a == b,
        _ => false,
    }
}

/// `path` made absolute with its symbolic links resolved, or, for a file that does not exist
/// yet, its canonical directory joined with its name.
fn resolved(path: &Path) -> Option<PathBuf> {
    if let Ok(path) = std::fs::canonicalize(path) {
        return Some(path);
    }
    let name = path.file_name()?;
    let dir = directory_of(path);
    std::fs::canonicalize(dir).ok().map(|dir| dir.join(name))
}

fn directory_of(path: &Path) -> &Path {
    path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."))
}

/// A staged output.
enum Staged {
    /// A regular file, or one not there yet: the temporary beside it holding its contents.
    File { path: PathBuf, tmp: tempfile::NamedTempFile },
    /// A device or a pipe: the contents, written into it at the commit.
    Stream { path: PathBuf, contents: Vec<u8> },
}

impl Staged {
    fn path(&self) -> &Path {
        match self {
            Staged::File { path, .. } | Staged::Stream { path, .. } => path,
        }
    }
}

/// The outputs of one command, written all at the end or not at all.
///
/// ```no_run
/// # use swg_host::report::output::Outputs;
/// # use std::path::Path;
/// let mut outputs = Outputs::new([Path::new("rec.csv")]);
/// outputs.refuse_inputs([Path::new("fit.json")])?; // before the work: fails fast
/// outputs.stage(Path::new("fit.json"), b"{}")?;
/// outputs.stage(Path::new("loop.svg"), b"<svg/>")?;
/// outputs.commit()?; // renames both; on an error above, neither is touched
/// # Ok::<(), swg_host::report::output::OutputError>(())
/// ```
pub struct Outputs {
    inputs: Vec<PathBuf>,
    staged: Vec<Staged>,
    /// Directories this set created, removed again (when empty) unless committed.
    created_dirs: Vec<PathBuf>,
    committed: bool,
}

impl Outputs {
    /// An empty set for a command that reads `inputs`.
    pub fn new<'a>(inputs: impl IntoIterator<Item = &'a Path>) -> Outputs {
        Outputs {
            inputs: inputs.into_iter().map(Path::to_owned).collect(),
            staged: Vec::new(),
            created_dirs: Vec::new(),
            committed: false,
        }
    }

    /// Checks, before any work, that none of `outputs` is an input or named twice.
    pub fn refuse_inputs<'a>(&self, outputs: impl IntoIterator<Item = &'a Path>) -> Result<(), OutputError> {
        let outputs: Vec<&Path> = outputs.into_iter().collect();
        for (index, output) in outputs.iter().enumerate() {
            self.check(output)?;
            if outputs[..index].iter().any(|earlier| same_file(earlier, output)) {
                return Err(OutputError::Twice { path: output.to_path_buf() });
            }
        }
        Ok(())
    }

    fn check(&self, output: &Path) -> Result<(), OutputError> {
        if self.inputs.iter().any(|input| same_file(input, output)) {
            return Err(OutputError::IsInput { path: output.to_owned() });
        }
        if self.staged.iter().any(|staged| same_file(staged.path(), output)) {
            return Err(OutputError::Twice { path: output.to_owned() });
        }
        Ok(())
    }

    /// Creates `dir` for outputs, in a directory that exists (as `mkdir`, not `mkdir -p`: a
    /// mistyped path is an error, not a tree of new directories); removed again if the set is not
    /// committed and the directory is still empty.
    pub fn create_dir(&mut self, dir: &Path) -> Result<(), OutputError> {
        if dir.exists() {
            return if dir.is_dir() { Ok(()) } else { Err(OutputError::NotADirectory { path: dir.to_owned() }) };
        }
        let parent = directory_of(dir);
        if !parent.is_dir() {
            return Err(OutputError::NoDirectory { path: dir.to_owned(), dir: parent.to_owned() });
        }
        std::fs::create_dir(dir).map_err(|e| OutputError::write(dir, e))?;
        // Innermost first, so that removing them in order empties each parent.
        self.created_dirs.insert(0, dir.to_owned());
        Ok(())
    }

    /// Writes `contents` to a temporary file in `path`'s directory (synced to disk); `path`
    /// itself is replaced only by [`Outputs::commit`].
    pub fn stage(&mut self, path: &Path, contents: &[u8]) -> Result<(), OutputError> {
        self.check(path)?;
        if let Ok(metadata) = std::fs::metadata(path) {
            if metadata.is_dir() {
                return Err(OutputError::IsDirectory { path: path.to_owned() });
            }
            if !metadata.is_file() {
                self.staged.push(Staged::Stream { path: path.to_owned(), contents: contents.to_vec() });
                return Ok(());
            }
        }
        let dir = directory_of(path);
        if !dir.is_dir() {
            return Err(OutputError::NoDirectory { path: path.to_owned(), dir: dir.to_owned() });
        }
        // A temporary file is private (0600); the result is an ordinary file others may read.
        #[cfg(unix)]
        let tmp = {
            use std::os::unix::fs::PermissionsExt;
            tempfile::Builder::new()
                .prefix(".swg-")
                .permissions(std::fs::Permissions::from_mode(0o644))
                .tempfile_in(dir)
        };
        #[cfg(not(unix))]
        let tmp = tempfile::Builder::new().prefix(".swg-").tempfile_in(dir);
        let mut tmp = tmp.map_err(|e| OutputError::write(path, e))?;
        tmp.write_all(contents).map_err(|e| OutputError::write(path, e))?;
        tmp.as_file().sync_all().map_err(|e| OutputError::write(path, e))?;
        self.staged.push(Staged::File { path: path.to_owned(), tmp });
        Ok(())
    }

    /// Renames every staged file over its destination, and writes into every device or pipe,
    /// in the order staged. A rename within one directory does not fail once the temporary is
    /// written; should one fail anyway, the temporaries not yet renamed are removed.
    pub fn commit(mut self) -> Result<(), OutputError> {
        for staged in std::mem::take(&mut self.staged) {
            match staged {
                Staged::File { path, tmp } => {
                    tmp.persist(&path).map_err(|e| OutputError::write(&path, e.error))?;
                }
                Staged::Stream { path, contents } => std::fs::OpenOptions::new()
                    .write(true)
                    .open(&path)
                    .and_then(|mut stream| stream.write_all(&contents))
                    .map_err(|e| OutputError::write(&path, e))?,
            }
        }
        self.committed = true;
        Ok(())
    }
}

impl Drop for Outputs {
    fn drop(&mut self) {
        // The staged temporaries delete themselves when dropped; then the directories made.
        self.staged.clear();
        if !self.committed {
            for dir in &self.created_dirs {
                let _ = std::fs::remove_dir(dir);
            }
        }
    }
}

/// Writes one file whole: [`Outputs`] with a single output and no inputs.
pub fn write_atomically(path: &Path, contents: &[u8]) -> std::io::Result<()> {
    let mut outputs = Outputs::new([]);
    let io = |e: OutputError| match e {
        OutputError::Write { source, .. } => source,
        other => std::io::Error::other(other.to_string()),
    };
    outputs.stage(path, contents).map_err(io)?;
    outputs.commit().map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replaces_the_file_whole_and_readable() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.json");
        std::fs::write(&path, "old").unwrap();
        write_atomically(&path, b"new").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "no temporary file left behind");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            assert_eq!(std::fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o644);
        }
    }

    #[test]
    fn writes_all_or_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.json"), dir.path().join("b.svg"));
        std::fs::write(&a, "old").unwrap();
        let mut outputs = Outputs::new([]);
        outputs.stage(&a, b"new").unwrap();
        assert!(outputs.stage(&dir.path().join("no/such/dir/c.svg"), b"x").is_err());
        drop(outputs);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "temporaries removed");

        let mut outputs = Outputs::new([]);
        outputs.stage(&a, b"new").unwrap();
        outputs.stage(&b, b"<svg/>").unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old", "nothing replaced before the commit");
        outputs.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "<svg/>");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    /// A rename over `/dev/null` as root puts a file in its place, which every later
    /// `> /dev/null` then fills; a named pipe stands in for the device here.
    #[cfg(unix)]
    #[test]
    fn a_device_or_pipe_is_written_into_not_replaced() {
        use std::io::Read;
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let pipe = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&pipe).status().unwrap();
        assert!(made.success(), "mkfifo");
        let reader = {
            let pipe = pipe.clone();
            std::thread::spawn(move || {
                let mut read = String::new();
                std::fs::File::open(pipe).unwrap().read_to_string(&mut read).unwrap();
                read
            })
        };
        let mut outputs = Outputs::new([]);
        outputs.stage(&pipe, b"through the pipe").unwrap();
        outputs.commit().unwrap();
        assert!(std::fs::metadata(&pipe).unwrap().file_type().is_fifo(), "still a pipe");
        assert_eq!(reader.join().unwrap(), "through the pipe");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "no temporary file left behind");
    }

    #[test]
    fn a_directory_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mut outputs = Outputs::new([]);
        assert!(matches!(outputs.stage(dir.path(), b"x"), Err(OutputError::IsDirectory { .. })));
    }

    #[test]
    fn refuses_an_input_and_a_path_named_twice() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("rec.csv");
        std::fs::write(&input, "data").unwrap();
        let outputs = Outputs::new([input.as_path()]);
        let dotted = dir.path().join(".").join("rec.csv");
        assert!(matches!(outputs.refuse_inputs([dotted.as_path()]), Err(OutputError::IsInput { .. })));
        #[cfg(unix)]
        {
            let link = dir.path().join("link.csv");
            std::fs::hard_link(&input, &link).unwrap();
            assert!(matches!(outputs.refuse_inputs([link.as_path()]), Err(OutputError::IsInput { .. })));
        }
        let new = dir.path().join("new.json");
        let new_dotted = dir.path().join(".").join("new.json");
        assert!(matches!(outputs.refuse_inputs([new.as_path(), new_dotted.as_path()]), Err(OutputError::Twice { .. })));
        assert!(outputs.refuse_inputs([new.as_path()]).is_ok());
        assert_eq!(std::fs::read_to_string(&input).unwrap(), "data");
    }

    #[test]
    fn removes_the_directories_it_made_unless_committed() {
        let dir = tempfile::tempdir().unwrap();
        let plots = dir.path().join("plots/deep");
        let mut outputs = Outputs::new([]);
        outputs.create_dir(&dir.path().join("plots")).unwrap();
        outputs.create_dir(&plots).unwrap();
        outputs.stage(&plots.join("a.svg"), b"x").unwrap();
        drop(outputs);
        assert!(!dir.path().join("plots").exists());
    }

    /// A directory in one that does not exist is refused, not made with its parents: a
    /// mistyped `--plot` left a tree of new directories behind.
    #[test]
    fn a_directory_is_made_only_in_one_that_exists() {
        let dir = tempfile::tempdir().unwrap();
        let error = Outputs::new([]).create_dir(&dir.path().join("typo/plots")).unwrap_err();
        assert!(matches!(error, OutputError::NoDirectory { .. }), "{error}");
        assert!(!dir.path().join("typo").exists());
    }

    #[test]
    fn a_file_is_not_taken_for_a_directory() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("plots");
        std::fs::write(&file, "data").unwrap();
        let error = Outputs::new([]).create_dir(&file).unwrap_err();
        assert!(matches!(error, OutputError::NotADirectory { .. }), "{error}");
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "data");
    }
}
