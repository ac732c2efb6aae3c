//! Small neural-network helpers built from primitives.
