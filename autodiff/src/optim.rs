//! Optimisers working on tensors outside the tape.
