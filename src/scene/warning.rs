use std::fmt;
use std::path::PathBuf;

/// Something a load went on past: what was approximated, skipped or replaced, and where. The
/// library returns these with the scene; the caller shows them (the CLI prints each as one
/// `warning: ...` line).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Warning {
    /// The file the warning is about, when there is one.
    pub file: Option<PathBuf>,
    /// Its line (pbrt files).
    pub line: Option<u32>,
    /// The entry of the file (`material.name`, `mesh[0]`), where the format has entries.
    pub entry: Option<String>,
    pub message: String,
}

impl Warning {
    /// A warning about `file` as a whole.
    pub fn file(file: impl Into<PathBuf>, message: impl Into<String>) -> Warning {
        Warning {
            file: Some(file.into()),
            line: None,
            entry: None,
            message: message.into(),
        }
    }

    /// A warning about a line of `file`.
    pub fn at(file: impl Into<PathBuf>, line: u32, message: impl Into<String>) -> Warning {
        Warning {
            line: Some(line),
            ..Warning::file(file, message)
        }
    }

    /// A warning about an entry of `file`.
    pub fn entry(
        file: impl Into<PathBuf>,
        entry: impl Into<String>,
        message: impl Into<String>,
    ) -> Warning {
        Warning {
            entry: Some(entry.into()),
            ..Warning::file(file, message)
        }
    }
}

/// `file:line: entry: message`, each part where known: the line users see after `warning: `.
impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{}", file.display())?;
            if let Some(line) = self.line {
                write!(f, ":{line}")?;
            }
            write!(f, ": ")?;
        }
        if let Some(entry) = &self.entry {
            write!(f, "{entry}: ")?;
        }
        write!(f, "{}", self.message)
    }
}
