//! Safe wrapper around Embree 3: the only `unsafe` code touching Embree.
