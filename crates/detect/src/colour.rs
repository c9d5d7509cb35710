//! Which pixels may be apple skin: red, bicolour and yellow apples, not
//! leaves, bark, sky, grey posts, white labels or optic-yellow tennis balls.
//!
//! The test is on the image's own bytes (sRGB), on ratios, so that it holds
//! in sun and shade alike: red at least [`MIN_RED_OVER_GREEN`] of green (a
//! green leaf's red is about 0.5-0.8 of its green, a yellow apple's 1.0-1.2
//! and a red one's 2 and more; an optic-yellow ball's 0.8-0.9), saturated
//! at least [`MIN_SATURATION`] (apple skin's pigments absorb blue almost
//! wholly; bark, soil, sky, white and grey surfaces are duller), and bright
//! enough for the ratios to mean anything ([`MIN_BRIGHTNESS_DN`]).

use image::{GrayImage, Luma, RgbImage};

/// Least red over green of apple skin: yellow apples ('Golden Delicious')
/// reflect about as much red as green (Saeys et al. 2008 skin spectra,
/// ../shared/REFERENCES.md), green leaves and green apples less.
pub const MIN_RED_OVER_GREEN: f32 = 0.95;

/// Least saturation, (max - min) / max: apple skin's anthocyanins and
/// carotenoids absorb blue almost wholly (red 0.75-0.85, yellow 0.7-0.8);
/// brown bark and soil reach about 0.55, sky, white and grey surfaces
/// less.
pub const MIN_SATURATION: f32 = 0.6;

/// Darkest brightest channel (DN) whose colour is trusted: below it the
/// sensor's noise decides the ratios.
pub const MIN_BRIGHTNESS_DN: u8 = 30;

/// Whether a pixel may be apple skin (see the module docs).
#[inline]
pub fn is_fruit_coloured(rgb: [u8; 3]) -> bool {
    skin_coloured(rgb, MIN_RED_OVER_GREEN)
}

/// Bright enough, saturated at least [`MIN_SATURATION`], and red at least
/// `min_red_over_green` of green.
#[inline]
fn skin_coloured([r, g, b]: [u8; 3], min_red_over_green: f32) -> bool {
    let (max, min) = (r.max(g).max(b), r.min(g).min(b));
    max >= MIN_BRIGHTNESS_DN
        && f32::from(r) >= min_red_over_green * f32::from(g)
        && f32::from(max - min) >= MIN_SATURATION * f32::from(max)
}

/// Least red over green of an apple's ground colour, the yellow-green skin
/// beside a blush: it joins a fruit it touches, never starts one (sunlit
/// leaves come close to it, shaded ones stay near 0.5).
pub const MIN_GROUND_RED_OVER_GREEN: f32 = 0.75;

/// Whether a pixel may be an apple's ground colour: [`is_fruit_coloured`]
/// with red down to [`MIN_GROUND_RED_OVER_GREEN`] of green.
#[inline]
pub fn is_ground_coloured(rgb: [u8; 3]) -> bool {
    skin_coloured(rgb, MIN_GROUND_RED_OVER_GREEN)
}

/// The fruit-coloured pixels of `image`: 255 where [`is_fruit_coloured`], 0
/// elsewhere.
pub fn fruit_mask(image: &RgbImage) -> GrayImage {
    let (width, height) = image.dimensions();
    let data = image.pixels().map(|p| if is_fruit_coloured(p.0) { 255 } else { 0 }).collect();
    GrayImage::from_raw(width, height, data).unwrap_or_else(|| GrayImage::new(width, height))
}

/// Whether the mask holds fruit at (u, v) (false outside the image).
pub(crate) fn fruit_at(mask: &GrayImage, u: i64, v: i64) -> bool {
    u >= 0
        && v >= 0
        && (u as u64) < u64::from(mask.width())
        && (v as u64) < u64::from(mask.height())
        && mask.get_pixel(u as u32, v as u32) == &Luma([255])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn apples_are_fruit_coloured_leaves_sky_labels_and_balls_are_not() {
        let fruit = [[180, 40, 30], [90, 20, 18], [255, 120, 60], [200, 185, 60], [140, 120, 40]];
        let not = [
            [60, 110, 40],   // leaf in shade
            [63, 47, 29],    // bark
            [90, 50, 40],    // reddish bark
            [150, 190, 70],  // sunlit leaf
            [200, 220, 240], // sky
            [240, 240, 235], // white label
            [120, 120, 118], // grey post
            [200, 230, 60],  // optic-yellow tennis ball
            [20, 5, 5],      // too dark to tell
            [90, 160, 60],   // green apple (a stated limit)
        ];
        for rgb in fruit {
            assert!(is_fruit_coloured(rgb), "{rgb:?}");
        }
        for rgb in not {
            assert!(!is_fruit_coloured(rgb), "{rgb:?}");
        }
    }
}
