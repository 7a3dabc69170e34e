//! Seeded generators of the IMU noise processes: quantization, white, first-order Gauss-Markov
//! (exact discretisation), random walk and flicker (1/f).
