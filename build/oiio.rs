//! Compiles the OpenImageIO shim (`ffi/oiio.cc`) and its cxx bridge
//! (`src/image/oiio.rs`). OpenImageIO is found through pkg-config only:
//! Debian's `libopenimageio-dev` ships `OpenImageIO.pc`, and pkg-config also
//! emits the link flags.

pub fn build() {
    for file in ["ffi/oiio.h", "ffi/oiio.cc", "src/image/oiio.rs"] {
        println!("cargo:rerun-if-changed={file}");
    }
    let lib = match pkg_config::Config::new()
        .atleast_version("2.2")
        .probe("OpenImageIO")
    {
        Ok(lib) => lib,
        Err(e) => {
            let detail = e.to_string().replace('\n', " ");
            println!("cargo:warning=pkg-config could not find OpenImageIO: {detail}");
            panic!("OpenImageIO not found: install Debian's libopenimageio-dev");
        }
    };
    cxx_build::bridge("src/image/oiio.rs")
        .file("ffi/oiio.cc")
        .includes(&lib.include_paths)
        .std("c++17")
        .warnings(true)
        .compile("rangewalk-oiio");
}
