//! Tile sampling: the pixels of one sample of a frame's tiles (the `sampled`
//! mode).

use crate::sampling::SamplingError;

/// The pixels of one tile sample: the `tile` x `tile` tiles `(tx, ty)` with
/// `(tx + 3 ty) mod every == offset`, in raster order. Shifting each tile row by 3
/// spreads the kept tiles over the frame (a plain `index mod every` keeps whole
/// columns when `every` divides the tiles per row); the `every` offsets partition
/// the frame.
pub fn tile_sample(
    w: u32,
    h: u32,
    tile: u32,
    every: u32,
    offset: u32,
) -> Result<Vec<u32>, SamplingError> {
    if tile == 0 || tile > w.min(h) {
        return Err(SamplingError::Invalid(format!(
            "--tile {tile} must be between 1 and the frame's smaller side ({}); choose a smaller tile",
            w.min(h)
        )));
    }
    if every == 0 {
        return Err(SamplingError::Invalid(
            "--sample-every 0 keeps nothing; give 1 (every tile) or more".into(),
        ));
    }
    let keep = |x: u32, y: u32| ((x / tile) + 3 * (y / tile)) % every == offset % every;
    let v: Vec<u32> = (0..h)
        .flat_map(|y| (0..w).filter(move |&x| keep(x, y)).map(move |x| y * w + x))
        .collect();
    if v.is_empty() {
        return Err(SamplingError::Invalid(format!(
            "a {w}x{h} frame has too few {tile}x{tile} tiles for one in {every}; use a smaller --tile or --sample-every"
        )));
    }
    Ok(v)
}
