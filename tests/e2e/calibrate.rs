//! End-to-end tests for the calibrate commands.
