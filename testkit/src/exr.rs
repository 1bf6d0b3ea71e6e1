//! Reading OpenEXR files (any compression the `exr` crate reads) into `f32`
//! planes by channel name, independent of the readers the crates under test
//! ship.

use std::path::Path;

/// Width, height and one plane (row-major) per name in `names`, from the
/// first layer of the file.
pub fn read_channels(path: &Path, names: &[&str]) -> Result<(usize, usize, Vec<Vec<f32>>), String> {
    let img = ::exr::prelude::read_all_flat_layers_from_file(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let layer = img.layer_data.first().ok_or_else(|| format!("{}: no layer", path.display()))?;
    let size = layer.size;
    let planes = names
        .iter()
        .map(|name| {
            layer
                .channel_data
                .list
                .iter()
                .find(|c| c.name.to_string() == *name)
                .map(|c| c.sample_data.values_as_f32().collect())
                .ok_or_else(|| format!("{}: no channel {name}", path.display()))
        })
        .collect::<Result<Vec<Vec<f32>>, String>>()?;
    Ok((size.width(), size.height(), planes))
}

/// Width, height and interleaved R, G, B of the first layer.
pub fn read_rgb(path: &Path) -> Result<(usize, usize, Vec<f32>), String> {
    let (w, h, p) = read_channels(path, &["R", "G", "B"])?;
    Ok((w, h, (0..w * h).flat_map(|i| [p[0][i], p[1][i], p[2][i]]).collect()))
}
