//! File output that never leaves a half-written result: every file is
//! written to a temporary sibling and renamed into place.
//!
//! Every change this module makes to the file system (a file written, a
//! folder created, a staging folder committed) holds a shared lock;
//! [`freeze_output`] takes it exclusively. An abort (the CLI's second
//! Ctrl-C) freezes the output before it removes the unfinished folders and
//! then ends the process, so no write can recreate a folder after its
//! removal, and none is cut in half.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{RwLock, RwLockReadGuard, RwLockWriteGuard};

/// Shared by the file-system changes of this module, exclusive in [`freeze_output`].
static OUTPUT_CHANGES: RwLock<()> = RwLock::new(());

fn changing_output() -> RwLockReadGuard<'static, ()> {
    OUTPUT_CHANGES.read().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Waits until the writes under way have finished and blocks every later
/// one (file, folder, commit) for as long as the guard lives. For a process
/// that is about to end: it removes what it must, with the output frozen,
/// and exits while still holding the guard. (No temporary file of
/// [`write_atomic`] exists then: each is renamed or removed under the
/// shared lock.)
pub fn freeze_output() -> RwLockWriteGuard<'static, ()> {
    OUTPUT_CHANGES.write().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// An output file that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {path}: {source}")]
pub struct WriteError {
    pub path: PathBuf,
    pub source: std::io::Error,
}

/// Writes `bytes` to `path` atomically (temporary file in the same folder,
/// flushed, then renamed). Creates missing parent folders.
///
/// ```
/// let dir = std::env::temp_dir().join("lucent-doc-io");
/// lucent::io::write_atomic(&dir.join("a.txt"), b"hello").unwrap();
/// assert_eq!(std::fs::read(dir.join("a.txt")).unwrap(), b"hello");
/// ```
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let err = |source| WriteError { path: path.to_path_buf(), source };
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let _changing = changing_output();
    create_folder_unlocked(parent).map_err(err)?;
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = parent.join(format!(".{name}.{}.tmp", std::process::id()));
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        let _registered = interrupt::Registered::new(&tmp);
        f.write_all(bytes)?;
        f.sync_all()?;
        mark_before_writing_into(parent)?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(err)
}

/// Writes several files as one output: each to a temporary sibling first,
/// then all renamed into place, so an error (a full disk, a folder where a
/// file goes) leaves none of them new or half-written, and Ctrl-C or SIGTERM
/// during the renames is acted on only after the last one. The files of one
/// result (an image and its sidecar JSON) are never found apart.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("lucent-doc-files-{}", std::process::id()));
/// std::fs::create_dir_all(dir.join("b.json")).unwrap(); // a folder where a file goes
/// let (a, b) = (dir.join("a.exr"), dir.join("b.json"));
/// assert!(lucent::io::write_files_atomic(&[(&a, b"image"), (&b, b"{}")]).is_err());
/// assert!(!a.exists(), "nothing of the set is written when one file cannot be");
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn write_files_atomic(files: &[(&Path, &[u8])]) -> Result<(), WriteError> {
    let _changing = changing_output();
    let mut temps: Vec<(PathBuf, &Path, interrupt::Registered)> = Vec::new();
    let remove_temps = |temps: &[(PathBuf, &Path, interrupt::Registered)]| {
        for (tmp, _, _) in temps {
            let _ = std::fs::remove_file(tmp);
        }
    };
    for &(path, bytes) in files {
        let err = |source| WriteError { path: path.to_path_buf(), source };
        if path.is_dir() {
            remove_temps(&temps);
            return Err(err(std::io::Error::new(std::io::ErrorKind::IsADirectory, "a folder is where the file goes")));
        }
        let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let tmp = parent.join(format!(".{name}.{}.tmp", std::process::id()));
        let written = create_folder_unlocked(parent).and_then(|()| {
            let mut f = std::fs::File::create(&tmp)?;
            let registered = interrupt::Registered::new(&tmp);
            f.write_all(bytes)?;
            f.sync_all()?;
            Ok(registered)
        });
        match written {
            Ok(registered) => temps.push((tmp, path, registered)),
            Err(source) => {
                let _ = std::fs::remove_file(&tmp);
                remove_temps(&temps);
                return Err(err(source));
            }
        }
    }
    // Every file is complete: move them in, a signal waiting until the last.
    let _deferred = interrupt::defer();
    let existed: Vec<bool> = temps.iter().map(|(_, p, _)| std::fs::symlink_metadata(p).is_ok()).collect();
    for (tmp, path, _) in &temps {
        let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if let Err(source) = mark_before_writing_into(parent) {
            remove_temps(&temps);
            return Err(WriteError { path: tmp.clone(), source });
        }
    }
    for (i, (tmp, path, _)) in temps.iter().enumerate() {
        if let Err(source) = std::fs::rename(tmp, path) {
            // Undo: the files this call added go, the unmoved temporaries too.
            for ((_, done, _), &was) in temps[..i].iter().zip(&existed) {
                if !was {
                    let _ = std::fs::remove_file(done);
                }
            }
            remove_temps(&temps[i..]);
            return Err(WriteError { path: path.to_path_buf(), source });
        }
    }
    Ok(())
}

/// `create_dir_all`, but a file where a folder is needed is said plainly
/// ("out exists and is not a folder" instead of "File exists (os error 17)").
pub fn create_folder(dir: &Path) -> std::io::Result<()> {
    let _changing = changing_output();
    create_folder_unlocked(dir)
}

/// [`create_folder`] for callers already holding the shared lock (a second
/// shared lock of the same thread could deadlock behind a waiting freeze).
fn create_folder_unlocked(dir: &Path) -> std::io::Result<()> {
    if let Some(problem) = dir.ancestors().filter(|a| !a.as_os_str().is_empty()).find_map(broken_link) {
        return Err(std::io::Error::new(std::io::ErrorKind::NotFound, problem));
    }
    if let Some(file) = dir.ancestors().find(|a| !a.as_os_str().is_empty() && a.exists() && !a.is_dir()) {
        return Err(std::io::Error::new(
            std::io::ErrorKind::NotADirectory,
            format!("{} exists and is not a folder", file.display()),
        ));
    }
    std::fs::create_dir_all(dir)
}

/// What is wrong with `path` when it is a symbolic link that leads nowhere:
/// a loop of links, or a link to something that does not exist (`None`
/// for anything else).
pub fn broken_link(path: &Path) -> Option<String> {
    let meta = std::fs::symlink_metadata(path).ok()?;
    if !meta.file_type().is_symlink() {
        return None;
    }
    let err = std::fs::metadata(path).err()?;
    #[cfg(unix)]
    if err.raw_os_error() == Some(libc::ELOOP) {
        return Some(format!("{} is a loop of symbolic links (it leads back to itself)", path.display()));
    }
    let _ = err;
    let target = std::fs::read_link(path).map(|t| t.display().to_string()).unwrap_or_else(|_| "?".into());
    Some(format!("{} is a symbolic link to {target}, which does not exist", path.display()))
}

/// The hidden file that marks a folder as lucent's output folder
/// ([`claim_output_folder`], [`mark_output_folder`]).
pub const OUTPUT_MARK: &str = ".lucent-output";

/// The manifest of a stage folder of `lucent run`, the pipeline's
/// `StageFiles::manifest` (spelled here, below the pipeline, for
/// [`check_output_folder`]'s test of a run's folder from before the mark).
pub const STAGE_MANIFEST: &str = "manifest.json";

/// An output folder lucent may not write into.
#[derive(Debug, thiserror::Error)]
pub enum OutputFolderError {
    #[error("{path}: the output folder exists and is not a folder")]
    NotAFolder { path: PathBuf },
    /// A dangling symbolic link or a loop of links where the output folder goes.
    #[error("{problem}; lucent does not write through it — fix or remove the link, or choose another output folder")]
    BrokenLink { problem: String },
    #[error(
        "{path}: the output folder already holds files lucent did not write ({example} …); lucent writes only into a \
         new or empty folder, or one an earlier lucent run wrote — choose another output folder"
    )]
    Foreign { path: PathBuf, example: String },
    #[error("{path}: cannot create the output folder: {source}")]
    Create { path: PathBuf, source: std::io::Error },
    /// Another run holds the folder's lock ([`lock_output_folder`]).
    #[error(
        "{path}: another lucent run (pid {pid} on {host}) is writing into this output folder ({lock}); wait for it \
         to end, or choose another output folder"
    )]
    Locked { path: PathBuf, lock: PathBuf, pid: u32, host: String },
}

/// The lock file of an output folder while a run writes into it.
pub const OUTPUT_LOCK: &str = ".lucent-lock";

/// An output folder's lock, held while a run writes into it (the lock
/// file is removed when this is dropped).
#[derive(Debug)]
pub struct OutputLock {
    path: PathBuf,
    /// A stale lock of an ended run that this one replaced (its pid and host).
    pub replaced_stale: Option<(u32, String)>,
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

fn host_name() -> String {
    #[cfg(unix)]
    {
        let mut buf = [0u8; 256];
        // SAFETY: gethostname writes at most buf.len() bytes into buf.
        if unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) } == 0 {
            let end = buf.iter().position(|b| *b == 0).unwrap_or(buf.len());
            return String::from_utf8_lossy(&buf[..end]).into_owned();
        }
    }
    "unknown host".into()
}

/// Whether process `pid` of this host is alive.
fn alive(pid: u32) -> bool {
    #[cfg(unix)]
    {
        let Ok(pid) = libc::pid_t::try_from(pid) else { return false };
        // SAFETY: kill with signal 0 only checks that the process exists.
        let r = unsafe { libc::kill(pid, 0) };
        r == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        true
    }
}

/// Takes the advisory lock of output folder `dir` (which exists) for a run:
/// [`OUTPUT_LOCK`] with this process's pid and host, made exclusively. A
/// lock held by a live process is [`OutputFolderError::Locked`]; one whose
/// process has ended on this host (a run killed with SIGKILL, a power cut)
/// is stale and replaced, and said so in [`OutputLock::replaced_stale`]. A
/// lock of another host is taken as held (its process cannot be checked).
pub fn lock_output_folder(dir: &Path) -> Result<OutputLock, OutputFolderError> {
    let path = dir.join(OUTPUT_LOCK);
    let host = host_name();
    let me = format!("{} {}\n", std::process::id(), host);
    let mut replaced_stale = None;
    for _ in 0..3 {
        match std::fs::OpenOptions::new().write(true).create_new(true).open(&path) {
            Ok(mut f) => {
                let _ = f.write_all(me.as_bytes());
                return Ok(OutputLock { path, replaced_stale });
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let text = std::fs::read_to_string(&path).unwrap_or_default();
                let mut words = text.split_whitespace();
                let pid: Option<u32> = words.next().and_then(|w| w.parse().ok());
                let holder: String = words.collect::<Vec<_>>().join(" ");
                match pid {
                    Some(pid) if holder != host || alive(pid) => {
                        return Err(OutputFolderError::Locked {
                            path: dir.to_path_buf(),
                            lock: path,
                            pid,
                            host: holder,
                        });
                    }
                    _ => {
                        replaced_stale = Some((pid.unwrap_or(0), holder));
                        let _ = std::fs::remove_file(&path);
                    }
                }
            }
            Err(source) => return Err(OutputFolderError::Create { path: dir.to_path_buf(), source }),
        }
    }
    Err(OutputFolderError::Create {
        path: dir.to_path_buf(),
        source: std::io::Error::other(format!("{}: cannot take the lock", path.display())),
    })
}

/// Whether lucent may write into `dir` as an output folder (it is not
/// created): it does not exist, or is an empty folder, or is marked as
/// lucent's ([`OUTPUT_MARK`] in it or in a folder above it), or holds a
/// stage folder of `lucent run` (a [`STAGE_MANIFEST`] one level down, from
/// before the mark). A folder of the user's with other files in it is
/// refused, so no output ever replaces or removes a file of theirs.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("lucent-doc-claim-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// lucent::io::check_output_folder(&dir).unwrap(); // empty
/// std::fs::write(dir.join("thesis.tex"), "mine").unwrap();
/// assert!(lucent::io::check_output_folder(&dir).is_err());
/// lucent::io::mark_output_folder(&dir).unwrap();
/// lucent::io::check_output_folder(&dir).unwrap();
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
pub fn check_output_folder(dir: &Path) -> Result<(), OutputFolderError> {
    let Ok(meta) = std::fs::metadata(dir) else {
        // A dangling link (writing through it would land elsewhere) or a
        // loop of links, here or in a folder above.
        if let Some(problem) = dir.ancestors().filter(|a| !a.as_os_str().is_empty()).find_map(broken_link) {
            return Err(OutputFolderError::BrokenLink { problem });
        }
        return match std::fs::symlink_metadata(dir) {
            Ok(_) => Err(OutputFolderError::NotAFolder { path: dir.to_path_buf() }),
            Err(_) => Ok(()),
        };
    };
    if !meta.is_dir() {
        return Err(OutputFolderError::NotAFolder { path: dir.to_path_buf() });
    }
    if is_marked(dir) {
        return Ok(());
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return Ok(()) };
    let mut example = None;
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() && p.join(STAGE_MANIFEST).is_file() {
            return Ok(());
        }
        example.get_or_insert_with(|| e.file_name().to_string_lossy().into_owned());
    }
    match example {
        None => Ok(()),
        Some(example) => Err(OutputFolderError::Foreign { path: dir.to_path_buf(), example }),
    }
}

/// Whether `dir` or a folder above it holds [`OUTPUT_MARK`].
fn is_marked(dir: &Path) -> bool {
    let absolute = std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf());
    absolute.ancestors().any(|a| a.join(OUTPUT_MARK).is_file())
}

/// The output folder of this process's command, until a file is written
/// into it ([`mark_when_written`]).
static UNMARKED_OUTPUT: std::sync::Mutex<Option<PathBuf>> = std::sync::Mutex::new(None);

/// Marks `dir` ([`mark_output_folder`]) just before the first file of this
/// process lands in it or below it ([`write_atomic`], [`write_files_atomic`]),
/// so a command killed after writing its files (a closed pipe on its last
/// line of output, SIGKILL) leaves a folder the next run may write into; a
/// command that writes nothing leaves no mark.
pub fn mark_when_written(dir: &Path) {
    let dir = std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf());
    *UNMARKED_OUTPUT.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(dir);
}

/// The mark of [`mark_when_written`], written when `folder` (where a file
/// is about to land) is the output folder or below it.
fn mark_before_writing_into(folder: &Path) -> std::io::Result<()> {
    let folder = std::path::absolute(folder).unwrap_or_else(|_| folder.to_path_buf());
    let mut pending = UNMARKED_OUTPUT.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let Some(dir) = pending.as_ref().filter(|d| folder.starts_with(d) && d.is_dir()) else { return Ok(()) };
    if !is_marked(dir) {
        let mark = dir.join(OUTPUT_MARK);
        std::fs::write(&mark, MARK_TEXT)?;
    }
    *pending = None;
    Ok(())
}

/// What [`OUTPUT_MARK`] holds.
const MARK_TEXT: &[u8] = b"written by lucent; lucent may replace its own files in this folder\n";

/// Marks `dir` (which exists) as lucent's output folder, so later runs may
/// write into it again ([`check_output_folder`]).
pub fn mark_output_folder(dir: &Path) -> Result<(), WriteError> {
    if is_marked(dir) {
        return Ok(());
    }
    write_atomic(&dir.join(OUTPUT_MARK), MARK_TEXT)
}

/// [`check_output_folder`], then creates the folder and marks it: for a
/// run that keeps its output folder even when it fails (`lucent run`).
pub fn claim_output_folder(dir: &Path) -> Result<(), OutputFolderError> {
    check_output_folder(dir)?;
    create_folder(dir).map_err(|source| OutputFolderError::Create { path: dir.to_path_buf(), source })?;
    mark_output_folder(dir).map_err(|e| OutputFolderError::Create { path: dir.to_path_buf(), source: e.source })
}

/// An output folder filled in a fresh hidden sibling folder and moved into
/// place only when complete: a run that fails leaves the output folder as it
/// was, and a run that succeeds leaves no stale file of an earlier run among
/// the ones the command owns ([`StagedDir::commit`]). Dropped without
/// `commit`, the staging folder is removed.
///
/// ```
/// let out = std::env::temp_dir().join(format!("lucent-doc-staged-{}", std::process::id()));
/// std::fs::create_dir_all(&out).unwrap();
/// std::fs::write(out.join("old.csv"), "stale").unwrap();
/// std::fs::write(out.join("notes.txt"), "the user's").unwrap();
/// lucent::io::mark_output_folder(&out).unwrap(); // an earlier run's folder
/// let stage = lucent::io::StagedDir::new(&out).unwrap();
/// lucent::io::write_atomic(&stage.path().join("new.csv"), b"1,2").unwrap();
/// stage.commit(|name| name.ends_with(".csv")).unwrap();
/// assert!(out.join("new.csv").exists() && out.join("notes.txt").exists() && !out.join("old.csv").exists());
/// # std::fs::remove_dir_all(&out).unwrap();
/// ```
#[derive(Debug)]
pub struct StagedDir {
    target: PathBuf,
    staging: PathBuf,
    committed: bool,
    /// The highest folder above the staging folder that `new` created (so a
    /// run that fails leaves no empty folder behind).
    created: Option<PathBuf>,
}

impl StagedDir {
    /// Creates the staging folder beside `target`, which must be a folder
    /// lucent may write into ([`check_output_folder`]); `target` itself is
    /// made only by [`StagedDir::commit`].
    pub fn new(target: &Path) -> Result<Self, OutputFolderError> {
        let err = |source| OutputFolderError::Create { path: target.to_path_buf(), source };
        let _changing = changing_output();
        check_output_folder(target)?;
        let parent = target.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let created = parent.ancestors().take_while(|a| !a.as_os_str().is_empty() && !a.exists()).last();
        let created = created.map(Path::to_path_buf);
        create_folder_unlocked(parent).map_err(err)?;
        let staging = Self::staging_path(target);
        if staging.exists() {
            std::fs::remove_dir_all(&staging).map_err(err)?;
        }
        std::fs::create_dir_all(&staging).map_err(err)?;
        Ok(Self { target: target.to_path_buf(), staging, committed: false, created })
    }

    /// The staging folder [`StagedDir::new`] makes for `target` (hidden,
    /// beside it, named with the process id): known before it exists, so a
    /// Ctrl-C handler can be told to remove it before it is made.
    pub fn staging_path(target: &Path) -> PathBuf {
        let parent = target.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
        let name = target.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
        parent.join(format!(".{name}.staging-{}", std::process::id()))
    }

    /// Where to write the output.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Removes from the output folder the entries `owned` claims (by name)
    /// and those the new output replaces, moves the new output in, and
    /// removes the staging folder. Other entries (the user's files) stay.
    pub fn commit(mut self, owned: impl Fn(&str) -> bool) -> Result<(), WriteError> {
        let err = |path: &Path| {
            let path = path.to_path_buf();
            move |source| WriteError { path, source }
        };
        let _changing = changing_output();
        create_folder_unlocked(&self.target).map_err(err(&self.target))?;
        if !is_marked(&self.target) {
            let mark = self.staging.join(OUTPUT_MARK);
            std::fs::write(&mark, MARK_TEXT).map_err(err(&mark))?;
        }
        let new: Vec<std::ffi::OsString> = std::fs::read_dir(&self.staging)
            .map_err(err(&self.staging))?
            .map(|e| e.map(|e| e.file_name()))
            .collect::<Result<_, _>>()
            .map_err(err(&self.staging))?;
        for entry in std::fs::read_dir(&self.target).map_err(err(&self.target))? {
            let entry = entry.map_err(err(&self.target))?;
            let name = entry.file_name();
            if owned(&name.to_string_lossy()) || new.contains(&name) {
                let p = entry.path();
                let removed = if p.is_dir() { std::fs::remove_dir_all(&p) } else { std::fs::remove_file(&p) };
                removed.map_err(err(&p))?;
            }
        }
        for name in &new {
            let to = self.target.join(name);
            std::fs::rename(self.staging.join(name), &to).map_err(err(&to))?;
        }
        self.committed = true;
        std::fs::remove_dir_all(&self.staging).map_err(err(&self.staging))
    }
}

/// A line of a user's text file as an error message quotes it: in quotes,
/// cut to 80 characters (with "…"), and with a hint when it holds semicolons
/// where commas are expected (a spreadsheet's export setting).
///
/// ```
/// assert_eq!(lucent::io::quoted_line("1;2;3"), "\"1;2;3\" (values separated by semicolons: export with commas)");
/// assert!(lucent::io::quoted_line(&"9,".repeat(100)).ends_with("…\""));
/// ```
pub fn quoted_line(line: &str) -> String {
    let shown: String = line.chars().take(80).collect();
    let text = if line.chars().count() > 80 { format!("{shown}…") } else { shown };
    let hint = if line.contains(';') && !line.contains(',') {
        " (values separated by semicolons: export with commas)"
    } else {
        ""
    };
    format!("{text:?}{hint}")
}

/// `message` with every staging folder of this process
/// ([`StagedDir::staging_path`], `.NAME.staging-PID`) and temporary file of
/// [`write_atomic`] (`.NAME.PID.tmp`) named as the output the user asked
/// for (`NAME`): an error while writing (a full disk) names the
/// destination the user knows, not a hidden path that is gone by the time
/// they look.
///
/// ```
/// let pid = std::process::id();
/// let m = format!("out/.run.staging-{pid}/profile.png: no space left; .a.csv.{pid}.tmp: no space");
/// assert_eq!(lucent::io::user_visible_paths(&m), "out/run/profile.png: no space left; a.csv: no space");
/// ```
pub fn user_visible_paths(message: &str) -> String {
    let pid = std::process::id();
    let mut out = message.to_string();
    for (suffix, leading) in [(format!(".staging-{pid}"), true), (format!(".{pid}.tmp"), true)] {
        let mut from = 0;
        while let Some(i) = out[from..].find(&suffix).map(|i| i + from) {
            // The start of the path component: after '/', whitespace or a quote.
            let start =
                out[..i].rfind(|c: char| c == '/' || c.is_whitespace() || c == '"' || c == '\'').map_or(0, |j| j + 1);
            if leading && out[start..].starts_with('.') && start + 1 < i {
                let name = out[start + 1..i].to_string();
                out.replace_range(start..i + suffix.len(), &name);
                from = start + name.len();
            } else {
                from = i + suffix.len();
            }
        }
    }
    out
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
            // The folders `new` made for the staging folder, if still empty.
            if let Some(top) = &self.created {
                for a in self.staging.ancestors().skip(1) {
                    if std::fs::remove_dir(a).is_err() || a == top.as_path() {
                        break;
                    }
                }
            }
        }
    }
}

/// Temporary files of [`write_atomic`] are removed when the process is
/// interrupted (SIGINT, SIGTERM) while writing them, so that Ctrl-C leaves no
/// hidden half-written file (an 86 MB `.x.exr.tmp` of `raw decode`).
/// [`remove_temporaries_on_interrupt`] installs the handler (the binary does
/// at start): it unlinks the files registered at that moment, then ends the
/// process with exit status 130 (interrupted), for SIGTERM and SIGHUP as for SIGINT. Up to 32 files being written at
/// once are tracked; the handler only reads atomics and fixed buffers and
/// calls `unlink` and `_exit` (async-signal-safe).
pub fn remove_temporaries_on_interrupt() {
    interrupt::install();
}

mod interrupt {
    use std::cell::UnsafeCell;
    use std::path::Path;
    use std::sync::atomic::{AtomicBool, AtomicI32, AtomicUsize, Ordering};

    const SLOTS: usize = 32;
    const LEN: usize = 4096;

    struct Paths(UnsafeCell<[[u8; LEN]; SLOTS]>);
    // SAFETY: a slot's bytes are written only by the thread that took it
    // (TAKEN) and before it is ARMED; the handler reads armed slots only.
    unsafe impl Sync for Paths {}

    static TAKEN: [AtomicBool; SLOTS] = [const { AtomicBool::new(false) }; SLOTS];
    static ARMED: [AtomicBool; SLOTS] = [const { AtomicBool::new(false) }; SLOTS];
    static PATHS: Paths = Paths(UnsafeCell::new([[0; LEN]; SLOTS]));

    /// A temporary file registered for removal on interrupt while alive.
    pub(super) struct Registered(Option<usize>);

    impl Registered {
        pub(super) fn new(path: &Path) -> Self {
            #[cfg(unix)]
            {
                use std::os::unix::ffi::OsStrExt;
                let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
                let bytes = path.as_os_str().as_bytes();
                if bytes.len() >= LEN || bytes.contains(&0) {
                    return Self(None);
                }
                for i in 0..SLOTS {
                    if TAKEN[i].compare_exchange(false, true, Ordering::AcqRel, Ordering::Relaxed).is_ok() {
                        // SAFETY: slot i is ours (TAKEN) and not armed, so nobody reads it.
                        let slot = unsafe { &mut (*PATHS.0.get())[i] };
                        slot[..bytes.len()].copy_from_slice(bytes);
                        slot[bytes.len()] = 0;
                        ARMED[i].store(true, Ordering::Release);
                        return Self(Some(i));
                    }
                }
            }
            let _ = path;
            Self(None)
        }
    }

    impl Drop for Registered {
        fn drop(&mut self) {
            if let Some(i) = self.0 {
                ARMED[i].store(false, Ordering::Release);
                TAKEN[i].store(false, Ordering::Release);
            }
        }
    }

    /// Callers of [`defer`] whose guard is alive, and the signal that came meanwhile.
    static DEFERRING: AtomicUsize = AtomicUsize::new(0);
    static PENDING: AtomicI32 = AtomicI32::new(0);

    /// While the guard lives, a SIGINT or SIGTERM is held back (recorded)
    /// and acted on when the last guard is dropped: a set of files being
    /// renamed into place is never cut in half.
    pub(super) struct Deferred(());

    pub(super) fn defer() -> Deferred {
        DEFERRING.fetch_add(1, Ordering::SeqCst);
        Deferred(())
    }

    impl Drop for Deferred {
        fn drop(&mut self) {
            if DEFERRING.fetch_sub(1, Ordering::SeqCst) == 1 {
                let signal = PENDING.swap(0, Ordering::SeqCst);
                #[cfg(unix)]
                if signal != 0 {
                    act(signal);
                }
                let _ = signal;
            }
        }
    }

    #[cfg(unix)]
    extern "C" fn on_signal(signal: libc::c_int) {
        // Recorded first, then held back if a set of files is being moved in
        // (its guard acts on it), else acted on at once.
        PENDING.store(signal, Ordering::SeqCst);
        if DEFERRING.load(Ordering::SeqCst) > 0 {
            return;
        }
        act(signal);
    }

    /// Removes the temporary files being written and ends the process with
    /// exit status 130.
    #[cfg(unix)]
    fn act(signal: libc::c_int) {
        for (i, armed) in ARMED.iter().enumerate() {
            if armed.load(Ordering::Acquire) {
                // SAFETY: an armed slot holds a NUL-terminated path; unlink is async-signal-safe.
                unsafe { libc::unlink((*PATHS.0.get())[i].as_ptr().cast()) };
            }
        }
        let _ = signal;
        const SAID: &[u8] = b"\ninterrupted: stopped (exit 130); no half-written file is left\n";
        // SAFETY: write(2) to stderr is async-signal-safe; a failed write changes nothing.
        let _ = unsafe { libc::write(2, SAID.as_ptr().cast(), SAID.len()) };
        // SAFETY: _exit is async-signal-safe. SIGINT and SIGTERM both end the
        // process as interrupted (exit status 130), as `lucent --help` states.
        unsafe { libc::_exit(130) };
    }

    pub(super) fn install() {
        #[cfg(unix)]
        // SAFETY: the handler only touches atomics, fixed buffers and async-signal-safe calls.
        unsafe {
            let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
            libc::signal(libc::SIGINT, handler);
            libc::signal(libc::SIGTERM, handler);
            // A closed terminal (SIGHUP) is a stop request like SIGTERM.
            libc::signal(libc::SIGHUP, handler);
        }
    }
}

/// Where `path` leads: symbolic links followed (a dangling one to its
/// target), `.` and `..` resolved, also when the path, or the end of it,
/// does not exist yet (the existing part canonical, the rest appended).
/// A symbolic-link loop is left as spelled after 40 links.
pub fn resolved(path: &Path) -> PathBuf {
    let mut p = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    for _ in 0..40 {
        if let Ok(c) = std::fs::canonicalize(&p) {
            return c;
        }
        match std::fs::read_link(&p) {
            Ok(target) => {
                p = match p.parent() {
                    Some(parent) => parent.join(target),
                    None => target,
                };
                continue;
            }
            Err(_) => {
                let (Some(parent), Some(name)) = (p.parent(), p.file_name()) else { return p };
                return resolved(parent).join(name);
            }
        }
    }
    p
}

/// The same file however its path is spelled (links, `./`, `..`): the
/// canonical path when it exists, else the absolute one. Two paths name one
/// file when their keys are equal.
pub fn file_key(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).or_else(|_| std::path::absolute(path)).unwrap_or_else(|_| path.to_path_buf())
}

/// The most [`read_text`] takes from a device or a pipe (a regular file is
/// read whole: its size is known before it is read).
pub const MAX_STREAM_TEXT_BYTES: u64 = 64 << 20;

/// `std::fs::read_to_string` for the files a user names: a device or a pipe
/// (`/dev/zero`, a FIFO) is read up to [`MAX_STREAM_TEXT_BYTES`] and refused
/// beyond, so a wrong path ends with an error instead of filling the memory.
pub fn read_text(path: impl AsRef<Path>) -> std::io::Result<String> {
    use std::io::Read;
    let path = path.as_ref();
    let meta = std::fs::metadata(path)?;
    if meta.is_dir() {
        return Err(std::io::Error::new(std::io::ErrorKind::InvalidInput, "a folder, not a file"));
    }
    if meta.is_file() {
        return std::fs::read_to_string(path);
    }
    let mut text = String::new();
    std::fs::File::open(path)?.take(MAX_STREAM_TEXT_BYTES + 1).read_to_string(&mut text)?;
    if text.len() as u64 > MAX_STREAM_TEXT_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not a regular file and more than {} MiB long", MAX_STREAM_TEXT_BYTES >> 20),
        ));
    }
    Ok(text)
}

/// Reads the optional word of a closed set under `key` (such as `phase =
/// "hg"`) with the library type's own parser, so a file takes every spelling
/// the flag takes; a wrong word is refused with the key and the valid names.
/// For `#[serde(default, deserialize_with = "…")]` through a function that
/// names the key.
pub fn named<'de, D, T>(d: D, key: &str) -> Result<Option<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: std::str::FromStr + strum::VariantArray + Copy + 'static,
    &'static str: From<T>,
{
    let word = <String as serde::Deserialize>::deserialize(d)?;
    word.parse().map(Some).map_err(|_| {
        let names: Vec<&'static str> = T::VARIANTS.iter().map(|&v| v.into()).collect();
        serde::de::Error::custom(format!("{key} {word:?}: expected one of {}", names.join(", ")))
    })
}

/// Serialises `value` as pretty JSON and writes it atomically.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<(), WriteError> {
    write_atomic(path, &json_bytes(path, value)?)
}

/// The bytes [`write_json`] writes: pretty JSON and a newline (`path` only
/// names the file in an error).
pub fn json_bytes<T: serde::Serialize>(path: &Path, value: &T) -> Result<Vec<u8>, WriteError> {
    let mut text = serde_json::to_string_pretty(value)
        .map_err(|e| WriteError { path: path.to_path_buf(), source: std::io::Error::other(e) })?;
    text.push('\n');
    Ok(text.into_bytes())
}

/// A file pattern that cannot be expanded ([`glob_files`]).
#[derive(Debug, thiserror::Error)]
pub enum GlobError {
    #[error("{spec}: wildcards are only supported in the file name, not in folders")]
    WildcardFolder { spec: String },
    #[error("{spec}: {source}")]
    Pattern { spec: String, source: globset::Error },
    #[error("{}: cannot list folder (from {spec}): {source}", dir.display())]
    List { spec: String, dir: PathBuf, source: std::io::Error },
}

/// Whether `spec` holds glob syntax: `*`, `?`, a class `[…]` or alternatives `{a,b}`.
pub fn is_glob(spec: &str) -> bool {
    spec.contains(['*', '?', '[', '{'])
}

/// The files a `DIR/PATTERN` spec names, sorted. The pattern applies to
/// the file name only, in `globset` syntax: `*`, `?`, classes `[0-9]` and
/// `[!a]`, alternatives `{jpg,png}`; the folder (`.` when none is given) is
/// taken literally. A spec that is an existing file, or has no glob syntax,
/// names at most itself. Folders are never matched.
///
/// ```
/// let dir = std::env::temp_dir().join("lucent-doc-glob");
/// for n in ["left01.jpg", "left02.jpg", "left10.jpg", "left01.png"] {
///     lucent::io::write_atomic(&dir.join(n), b"").unwrap();
/// }
/// let spec = format!("{}/left0[0-9].{{jpg,png}}", dir.display());
/// let names: Vec<String> = lucent::io::glob_files(&spec)
///     .unwrap()
///     .iter()
///     .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
///     .collect();
/// assert_eq!(names, ["left01.jpg", "left01.png", "left02.jpg"]);
/// ```
pub fn glob_files(spec: &str) -> Result<Vec<PathBuf>, GlobError> {
    let path = Path::new(spec);
    if path.is_file() || !is_glob(spec) {
        return Ok(if path.is_file() { vec![path.to_path_buf()] } else { vec![] });
    }
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
    if dir.is_some_and(|d| is_glob(&d.to_string_lossy())) {
        return Err(GlobError::WildcardFolder { spec: spec.to_string() });
    }
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let matcher = globset::GlobBuilder::new(&name)
        .literal_separator(true)
        .build()
        .map_err(|source| GlobError::Pattern { spec: spec.to_string(), source })?
        .compile_matcher();
    let dir = dir.unwrap_or(Path::new("."));
    let entries = std::fs::read_dir(dir).map_err(|source| GlobError::List {
        spec: spec.to_string(),
        dir: dir.to_path_buf(),
        source,
    })?;
    let mut out: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file() && p.file_name().is_some_and(|n| matcher.is_match(Path::new(n))))
        .collect();
    out.sort();
    Ok(out)
}

/// CSV text (`csv` crate: RFC 4180 quoting where a field needs it, `\n`
/// line ends) of a header and rows of fields. The fields come as text so
/// that each table keeps its own number formats.
///
/// ```
/// let rows = vec![vec!["a,b".to_string(), "1.5e0".to_string()]];
/// assert_eq!(lucent::io::csv_text(&["name", "value"], rows).unwrap(), "name,value\n\"a,b\",1.5e0\n");
/// ```
pub fn csv_text<R, F>(header: &[&str], rows: R) -> Result<String, csv::Error>
where
    R: IntoIterator<Item = Vec<F>>,
    F: AsRef<[u8]>,
{
    let mut w = csv::WriterBuilder::new().terminator(csv::Terminator::Any(b'\n')).from_writer(Vec::new());
    w.write_record(header)?;
    for row in rows {
        w.write_record(&row)?;
    }
    let bytes = w.into_inner().map_err(|e| csv::Error::from(e.into_error()))?;
    Ok(String::from_utf8_lossy(&bytes).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glob_files_match_classes_alternatives_and_wildcards_in_the_name_only() {
        let dir = tempfile::tempdir().unwrap();
        for n in ["left01.jpg", "left02.jpg", "left1.jpg", "left10.png", "a[1].jpg"] {
            write_atomic(&dir.path().join(n), b"").unwrap();
        }
        std::fs::create_dir(dir.path().join("left03.jpg")).unwrap();
        let names = |pattern: &str| -> Vec<String> {
            glob_files(&format!("{}/{pattern}", dir.path().display()))
                .unwrap()
                .iter()
                .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
                .collect()
        };
        assert_eq!(names("left[0-9][0-9].jpg"), ["left01.jpg", "left02.jpg"], "classes; folders are not files");
        assert_eq!(names("left?.jpg"), ["left1.jpg"]);
        assert_eq!(names("left*.{jpg,png}"), ["left01.jpg", "left02.jpg", "left1.jpg", "left10.png"]);
        assert_eq!(names("left[!0]*"), ["left1.jpg", "left10.png"]);
        assert_eq!(names("a[1].jpg"), ["a[1].jpg"], "an existing file is itself, brackets and all");
        assert!(names("*.exr").is_empty());
        assert!(names("nothing.jpg").is_empty());
        let e = glob_files(&format!("{}/*/x.jpg", dir.path().display())).unwrap_err().to_string();
        assert!(e.contains("only supported in the file name"), "{e}");
        let e = glob_files(&format!("{}/left[0-9.jpg", dir.path().display())).unwrap_err().to_string();
        assert!(e.contains("left[0-9.jpg"), "{e}");
    }

    #[test]
    fn replaces_whole_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub/x.csv");
        write_atomic(&p, b"first version, longer").unwrap();
        write_atomic(&p, b"second").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"second");
        let names: Vec<_> =
            std::fs::read_dir(dir.path().join("sub")).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names.len(), 1, "{names:?}");
    }

    #[test]
    fn unwritable_path_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("file");
        std::fs::write(&blocker, b"x").unwrap();
        let e = write_atomic(&blocker.join("child.txt"), b"y").unwrap_err();
        assert!(e.to_string().contains("child.txt"), "{e}");
    }
}
