//! What commands write, and the rules that keep a user's files safe:
//! output paths are checked before the work that fills them starts; files
//! are written under a temporary name beside their target and renamed when
//! whole; folders are made as `<out>.partial` and renamed when complete;
//! and no output replaces, or is written into, what rangewalk did not make
//! for it. So no failure, kill or full disk leaves a finished-looking
//! result, and no mistyped path destroys anything.

mod check;
mod file;
mod folder;

pub use check::{check_output, check_output_dir, OutputKind};
pub use file::{temporary_for, write_file, write_with};
pub use folder::{check_only, entries, numbered, Contents, Folder};
