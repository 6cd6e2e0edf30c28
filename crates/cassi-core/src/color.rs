//! Wavelength → colour: pseudo-RGB rendering of a cube.
