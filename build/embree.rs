//! Finds Embree 3 and generates its Rust bindings with bindgen.
//!
//! Search order: `EMBREE_DIR` (with `include/` and `lib/` under it), then the
//! system paths Debian's `libembree-dev` installs to. Embree 3 ships no
//! pkg-config file on Debian, so the probe is a plain header lookup.

use std::env;
use std::panic;
use std::path::{Path, PathBuf};

const MISSING: &str = "Embree 3 not found: install Debian's libembree-dev (apt-get install libembree-dev) or set EMBREE_DIR to a directory with include/embree3/rtcore.h and lib/";

pub fn build() {
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");
    let include = find_include();
    let header = include.join("embree3").join("rtcore.h");
    println!("cargo:rerun-if-changed={}", header.display());
    println!("cargo:rustc-link-lib=embree3");
    generate_bindings(&include, &header);
}

/// The include directory that holds `embree3/rtcore.h`; also emits the link
/// search path when `EMBREE_DIR` is set (system libraries need none).
fn find_include() -> PathBuf {
    if let Some(dir) = env::var_os("EMBREE_DIR") {
        let dir = PathBuf::from(dir);
        let include = dir.join("include");
        if !include.join("embree3").join("rtcore.h").is_file() {
            panic!(
                "{MISSING} (EMBREE_DIR={} has no include/embree3/rtcore.h)",
                dir.display()
            );
        }
        for lib in ["lib", "lib64"] {
            let lib = dir.join(lib);
            if lib.is_dir() {
                println!("cargo:rustc-link-search=native={}", lib.display());
            }
        }
        return include;
    }
    let system = Path::new("/usr/include");
    if system.join("embree3").join("rtcore.h").is_file() {
        return system.to_path_buf();
    }
    panic!("{MISSING}");
}

fn generate_bindings(include: &Path, header: &Path) {
    let builder = bindgen::Builder::default()
        .header(header.to_string_lossy())
        .clang_arg(format!("-I{}", include.display()))
        .allowlist_function("rtc.*")
        .allowlist_type("RTC.*")
        .allowlist_var("RTC.*")
        .newtype_enum("RTC.*")
        .derive_default(true)
        .parse_callbacks(Box::new(bindgen::CargoCallbacks::new()));
    // bindgen panics (rather than returning an error) when it cannot load
    // libclang; turn that into the one sentence a user can act on, with the
    // default hook silenced so its own report does not come first.
    let hook = panic::take_hook();
    panic::set_hook(Box::new(|_| {}));
    let generated = panic::catch_unwind(panic::AssertUnwindSafe(|| builder.generate()));
    panic::set_hook(hook);
    let bindings = match generated {
        Ok(Ok(bindings)) => bindings,
        Ok(Err(e)) => panic!("bindgen failed on {}: {e}", header.display()),
        Err(cause) => {
            let msg = cause
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| cause.downcast_ref::<&str>().copied())
                .unwrap_or("unknown error");
            panic!(
                "bindgen could not run libclang ({msg}): install libclang-dev (apt-get install libclang-dev) or set LIBCLANG_PATH"
            );
        }
    };
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let path = out.join("embree_sys.rs");
    bindings
        .write_to_file(&path)
        .unwrap_or_else(|e| panic!("cannot write {}: {e}", path.display()));
}
