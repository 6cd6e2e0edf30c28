//! Image-quality metrics: PSNR, SSIM, SAM.
