//! Rendering: the reference path tracer (and later id-images and base-image
//! shading), all through the `accel::RayEngine` interface.
