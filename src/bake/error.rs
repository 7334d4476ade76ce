//! What can go wrong in a bake job as a whole ([`BakeError`]); one input's failure is an
//! [`InputError`](quatcurve_anim::error::InputError) and the job goes on with the others.

/// Why a bake job could not start, or could not keep its manifest.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BakeError {
    /// An option outside its rules; `option` is its library name (`rate`, `max_texture_size`,
    /// `inputs`, ...), which is also its Python keyword; the command line shows its flag.
    #[error("{option} {reason}")]
    Option {
        /// The option's name.
        option: &'static str,
        /// What is wrong with it, said after the name.
        reason: String,
    },
    /// The job as a whole is inconsistent (two inputs writing the same outputs, a scheduler's
    /// index without its count).
    #[error("{0}")]
    Job(String),
    /// The manifest could not be written.
    #[error(transparent)]
    Manifest(#[from] quatcurve_eval::io::IoError),
}

impl BakeError {
    pub(crate) fn option(option: &'static str, reason: impl Into<String>) -> Self {
        Self::Option { option, reason: reason.into() }
    }
}
