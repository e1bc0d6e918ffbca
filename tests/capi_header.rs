//! The committed C header is what cbindgen generates from `src/capi` now.

use std::path::Path;

#[test]
fn the_committed_header_is_what_cbindgen_generates() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(root.join("cbindgen.toml"))
        .expect("cbindgen.toml is readable and valid");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(root)
        .with_config(config)
        .generate()
        .expect("cbindgen parses the crate")
        .write(&mut generated);
    let generated = String::from_utf8(generated).expect("the header is UTF-8");
    let path = root.join("include/rangewalk.h");
    if std::env::var_os("RANGEWALK_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("include/rangewalk.h is writable");
    }
    let committed = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        committed == generated,
        "{} differs from what cbindgen generates from src/capi; run `RANGEWALK_BLESS=1 cargo test --release --test capi_header` and commit it",
        path.display()
    );
}
