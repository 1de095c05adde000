//! Localization core: path-loss model, PLE/P0 estimation, grid MLE (float reference and fixed point).
#![no_std]
