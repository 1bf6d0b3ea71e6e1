//! A camera file (camera.json of `lucent calibrate`) through serde into
//! `Calibration` (whose camera model is validated on load), then every
//! pixel of a grid to a ray and the ray back to the image: an error or a
//! usable camera, never a panic or a hang.
#![no_main]
use libfuzzer_sys::fuzz_target;
use lucent_calib::camera::Calibration;

fuzz_target!(|data: &[u8]| {
    let Ok(cal) = serde_json::from_slice::<Calibration>(data) else { return };
    let cam = &cal.camera;
    let (w, h) = (cam.image_width as f64, cam.image_height as f64);
    for j in 0..=4 {
        for i in 0..=4 {
            let (u, v) = (i as f64 / 4.0 * (w - 1.0), j as f64 / 4.0 * (h - 1.0));
            if let Some(ray) = cam.pixel_to_ray(u, v) {
                let _ = cam.project(ray);
            }
        }
    }
});
