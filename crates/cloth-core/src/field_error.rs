//! A wrong field, named by its path in a scene file: what every check of
//! a spec, a material or a solver setting returns, and what the scene
//! reports as it is, with no text to take apart.

/// A field that is wrong, by its path (`panels[0].particles`,
/// `solver.newton.iterations`; relative to its table where the check
/// knows no more: `tensile_stiffness_n_m` for a material), and what is
/// wrong with it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{path}: {message}")]
pub struct FieldError {
    /// The field's path.
    pub path: String,
    /// What is wrong with it.
    pub message: String,
}

impl FieldError {
    /// `path` is wrong: `message`.
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        Self { path: path.into(), message: message.into() }
    }

    /// The same error with its path under `table` (`material`,
    /// `pins[2]`): `table.path`, or `table` alone for an empty path.
    pub fn within(self, table: &str) -> Self {
        let path = if self.path.is_empty() { table.to_string() } else { format!("{table}.{}", self.path) };
        Self { path, ..self }
    }
}

/// A shape's error, by its path relative to the shape table (`radius_m`,
/// `obj` for a mesh file that cannot be read).
impl From<cloth_collide::ShapeError> for FieldError {
    fn from(e: cloth_collide::ShapeError) -> Self {
        match e {
            cloth_collide::ShapeError::Invalid { field, message } => FieldError::new(field, message),
            cloth_collide::ShapeError::Mesh { path, message } => {
                FieldError::new("obj", format!("{}: {message}", path.display()))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_error_goes_under_its_tables() {
        let e = FieldError::new("iterations", "must be >= 1").within("newton").within("solver");
        assert_eq!(e.path, "solver.newton.iterations");
        assert_eq!(e.to_string(), "solver.newton.iterations: must be >= 1");
        assert_eq!(FieldError::new("", "missing").within("wind").path, "wind");
    }
}
