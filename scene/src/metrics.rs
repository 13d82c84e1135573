//! Image metrics against a reference: PSNR, SSIM (11×11 Gaussian window, σ = 1.5, K1 = 0.01,
//! K2 = 0.03, data range 1), tile-SSIM, max absolute error, and a difference heat-map.
//! To be completed: see issue "Foundation".
