//! Finds the native libraries behind the `embree` and `oiio` features and
//! generates or compiles their bindings. Each half lives in `build/`.

#[cfg(feature = "embree")]
#[path = "build/embree.rs"]
mod embree;
#[cfg(feature = "oiio")]
#[path = "build/oiio.rs"]
mod oiio;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    // The C ABI's shared library names itself, so that programs linked
    // against an installed copy find it by name (`make install`).
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,librangewalk.so");
    }
    #[cfg(feature = "embree")]
    embree::build();
    #[cfg(feature = "oiio")]
    oiio::build();
}
