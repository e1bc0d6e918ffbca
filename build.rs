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
    #[cfg(feature = "embree")]
    embree::build();
    #[cfg(feature = "oiio")]
    oiio::build();
}
