//! Image error against references and the experiments that reproduce the
//! paper's tables.
