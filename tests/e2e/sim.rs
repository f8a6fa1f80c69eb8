//! End-to-end tests for the sim commands.
