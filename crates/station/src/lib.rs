//! The application layer of spinbench: the `spinbench` command line.
