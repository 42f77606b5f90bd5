/// Errors for bad tracker input or parameters; the Python glue maps each to one exception.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TrackError {
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    #[error("invalid input: {0}")]
    InvalidInput(String),
}
