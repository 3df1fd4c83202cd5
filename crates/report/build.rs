//! rust-i18n reads the catalogue when the crate is compiled (a macro), and a
//! macro cannot tell Cargo what it read: this says it, so a change of
//! `locales/spinbench.yml` rebuilds the crate.
fn main() {
    println!("cargo:rerun-if-changed=../../locales");
    println!("cargo:rerun-if-changed=../../locales/spinbench.yml");
}
