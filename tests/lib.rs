//! Workspace-level end-to-end tests: the fracid binary on real files.
