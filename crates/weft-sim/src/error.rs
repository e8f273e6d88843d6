//! Simulation errors: each names the element, the SEC field or the frame and step.

/// Why a scene cannot be simulated, or a frame could not be computed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SimError {
    /// A parameter is outside its physical range.
    ///
    /// `element 'shirt': discrete_shell.poisson_ratio must be in [0, 0.5), got 0.5`
    #[error("element '{element}': {field} {message}")]
    BadParameter {
        /// Element name.
        element: String,
        /// `sec.field`.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The geometry cannot be simulated (a zero-area triangle, a zero-length segment, NaN).
    ///
    /// `element 'shirt': triangle 12 [4, 5, 6] has zero rest area`
    #[error("element '{element}': {message}")]
    BadGeometry {
        /// Element name.
        element: String,
        /// What is wrong.
        message: String,
    },
    /// An attachment names an element or vertices that do not exist.
    ///
    /// `attachment 'pins': vertex 4096 is out of range (element 'shirt' has 1024 vertices)`
    #[error("attachment '{attachment}': {message}")]
    BadAttachment {
        /// Attachment element name.
        attachment: String,
        /// What is wrong.
        message: String,
    },
    /// A step failed even after the allowed retries with smaller substeps.
    ///
    /// `frame 12, substep 3 of 4 (after 2 retries): Newton did not converge …`
    #[error(
        "frame {frame}, substep {substep} of {substeps} (after {retries} retries with smaller steps): {message}"
    )]
    StepFailed {
        /// Frame being computed.
        frame: i64,
        /// Substep (1-based).
        substep: usize,
        /// Substeps per frame.
        substeps: usize,
        /// Retries made.
        retries: usize,
        /// The solver's error.
        message: String,
    },
    /// A stop check (Ctrl-C, a time limit) ended the frame; the previous state stands.
    ///
    /// `stopped at frame 3, substep 2 of 4 (Newton iteration 5)`
    #[error("stopped at frame {frame}, substep {substep} of {substeps} ({detail})")]
    Interrupted {
        /// Frame being computed.
        frame: i64,
        /// Substep (1-based).
        substep: usize,
        /// Substeps per frame.
        substeps: usize,
        /// Where inside the substep.
        detail: String,
    },
    /// The scene would not fit in the memory allowed; nothing large was allocated.
    ///
    /// `the scene's 40000000 simulated vertices need about 76.29 GiB, more than …`
    #[error("{0}")]
    TooLarge(String),
    /// The scene's structure changed between frames (vertex counts, elements).
    ///
    /// `element 'shirt' has 1024 vertices at frame 5 but had 1089 at the start`
    #[error("{0}")]
    SceneChanged(String),
    /// A combination of settings and scene this version does not simulate.
    ///
    /// `integrator bdf2 does not step contacts yet: …`
    #[error("{0}")]
    Unsupported(String),
}
