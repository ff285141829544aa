//! The one error type of the library: every failure is a single line that
//! names the offending glTF object (`meshes[3].primitives[0]`) or file.

use std::path::PathBuf;

/// Result alias used across the pipeline.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can stop a bake. Each variant prints as one line.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The container (GLB header/chunks or JSON syntax) is malformed.
    #[error("invalid glTF container: {0}")]
    Container(String),
    /// The glTF document is structurally invalid; the string names the object.
    #[error("invalid glTF: {0}")]
    Invalid(String),
    /// The document uses a feature aobake cannot read.
    #[error("unsupported glTF: {0}")]
    Unsupported(String),
    /// The scene has nothing to bake.
    #[error("nothing to bake: {0}")]
    Empty(String),
    /// A limit that protects the machine was exceeded.
    #[error("limit exceeded: {0}")]
    Limit(String),
    /// A setting out of range, or one that contradicts another. `setting`
    /// is the library's name for it (a field of `BakeSettings` or
    /// `ReportSettings`, such as `sparse_rays`); the
    /// command line shows its flag instead (`--sparse-rays`). `detail`
    /// follows the name, separator included (see `Error::option`).
    #[error("invalid option: {setting}{detail}")]
    Option {
        setting: &'static str,
        detail: String,
    },
    /// The UV unwrapper failed.
    #[error("UV unwrap failed: {0}")]
    Unwrap(String),
    /// Encoding an image failed.
    #[error("encoding failed: {0}")]
    Encode(String),
    /// A set of shard partials cannot be merged (names the partial).
    #[error("merge refused: {0}")]
    Merge(String),

    /// The GPU backend failed (no adapter, a lost device, a refused
    /// shader): the message names the adapter and what failed.
    #[error("GPU: {0}")]
    Gpu(String),
}

impl Error {
    /// A bad value of `setting`: `message` reads on from its name
    /// ("0 is outside 1..=1024", "must be at least 1").
    pub(crate) fn option(setting: &'static str, message: impl std::fmt::Display) -> Self {
        Error::Option {
            setting,
            detail: format!(" {message}"),
        }
    }

    /// A bad `item` of list-valued `setting` (`setting: 'item': why`).
    #[cfg(feature = "cli")]
    pub(crate) fn option_item(setting: &'static str, item: &str, why: &str) -> Self {
        Error::Option {
            setting,
            detail: format!(": '{item}': {why}"),
        }
    }

    /// A setting that cannot work with the input or with another setting
    /// (`setting: why`).
    pub(crate) fn option_conflict(setting: &'static str, why: impl std::fmt::Display) -> Self {
        Error::Option {
            setting,
            detail: format!(": {why}"),
        }
    }

    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    /// Prefixes the message with the glTF object it concerns (e.g.
    /// `meshes[1].primitives[0] POSITION`), for errors that carry one.
    pub(crate) fn within(self, object: &str) -> Self {
        match self {
            Error::Invalid(m) if !m.starts_with(object) => Error::Invalid(format!("{object}: {m}")),
            Error::Limit(m) if !m.starts_with(object) => Error::Limit(format!("{object}: {m}")),
            Error::Unsupported(m) if !m.starts_with(object) => {
                Error::Unsupported(format!("{object}: {m}"))
            }
            other => other,
        }
    }
}
