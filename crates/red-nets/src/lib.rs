//! Dense neural networks (placeholder until the red-nets work lands).
