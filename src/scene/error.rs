//! The scene layer's error: what is wrong with a scene, its files or its
//! description, in the words shown to the user (file, line and the fix).

use std::fmt;

use crate::util::FileError;

#[derive(Debug)]
pub enum SceneError {
    /// The spec names no builtin scene and no `.toml` or `.obj` path.
    Unknown { spec: String },
    /// The scene (or the file) has no triangles.
    Empty(String),
    /// An OBJ or material library that does not parse (file and line named).
    MalformedObj(String),
    /// A vertex that is NaN or infinite, or beyond the datapath's range.
    BadVertex(String),
    /// A scene description (`.toml`) that does not parse or has a bad value.
    BadDesc(String),
    /// Any other value out of range: camera, light, materials, render settings.
    Invalid(String),
    /// A file that cannot be read.
    File(FileError),
    /// Where the inner error happened: a file, a line, a mesh of a description.
    At { at: String, inner: Box<SceneError> },
}

impl SceneError {
    /// The error with `at` (a file, `file:line`, a mesh) in front.
    pub fn at(self, at: impl Into<String>) -> SceneError {
        SceneError::At {
            at: at.into(),
            inner: Box::new(self),
        }
    }

    /// The error itself, without the places it was wrapped in.
    pub fn root(&self) -> &SceneError {
        match self {
            SceneError::At { inner, .. } => inner.root(),
            e => e,
        }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SceneError::Unknown { spec } => write!(
                f,
                "unknown scene '{spec}': give a builtin ({}) or a path ending in .toml or .obj",
                super::BUILTINS.join(", ")
            ),
            SceneError::Empty(m)
            | SceneError::MalformedObj(m)
            | SceneError::BadVertex(m)
            | SceneError::BadDesc(m)
            | SceneError::Invalid(m) => f.write_str(m),
            SceneError::File(e) => write!(f, "{e}"),
            SceneError::At { at, inner } => write!(f, "{at}: {inner}"),
        }
    }
}

impl std::error::Error for SceneError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SceneError::File(e) => Some(e),
            SceneError::At { inner, .. } => Some(inner.as_ref()),
            _ => None,
        }
    }
}
