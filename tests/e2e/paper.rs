//! End-to-end tests for the paper commands.
