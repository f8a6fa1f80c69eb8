//! End-to-end tests for the diagnose commands.
