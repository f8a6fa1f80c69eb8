//! End-to-end tests for the fk_ik commands.
