//! COLLADA 1.4.1 + CGL loader (to be written).
