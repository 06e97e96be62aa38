//! Shared helpers of palpa's workspace-level integration tests.
