//! Radio driver (in progress).
