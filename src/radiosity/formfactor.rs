//! Form factors: point-to-polygon analytic, visibility by shadow rays.
