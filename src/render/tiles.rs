//! Parts of a frame: a crop [`Region`] (`render --crop x0,y0,x1,y1`) and the split of a frame into `N` parts for a
//! render farm (`render --tile I/N`).
//!
//! **The split** ([`Region::band`]): part `I` of `N` is the horizontal band of whole rows
//! `I·H/N .. (I+1)·H/N` (integer division), full width. Bands keep every row whole (one contiguous block of the
//! image, the simplest thing to merge and to check), their heights differ by at most one row, and the split needs
//! nothing but `N` and the frame height, so every task of a job array computes its own part. `N` may be at most
//! the frame height (no empty parts).
//!
//! A pixel depends only on its own sample streams (see [`super`]), so a region renders exactly the pixels the full
//! frame has there, bit for bit.

/// A rectangle of pixels `x0..x1` × `y0..y1` (half-open, `(0, 0)` top left) of a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl Region {
    /// The whole `width` × `height` frame.
    pub fn full(width: u32, height: u32) -> Region {
        Region {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        }
    }

    /// Parses `x0,y0,x1,y1` (the `--crop` syntax).
    pub fn parse(s: &str) -> Result<Region, String> {
        let v: Vec<u32> = s
            .split(',')
            .map(|p| p.trim().parse::<u32>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("expected x0,y0,x1,y1 (pixels), got `{s}`"))?;
        let [x0, y0, x1, y1] = v[..] else {
            return Err(format!("expected x0,y0,x1,y1 (pixels), got `{s}`"));
        };
        if x0 >= x1 || y0 >= y1 {
            return Err(format!("crop `{s}` is empty: need x0 < x1 and y0 < y1"));
        }
        Ok(Region { x0, y0, x1, y1 })
    }

    /// Part `index` (0-based) of `count` of a `width` × `height` frame: a band of whole rows (see the
    /// [module docs](self)).
    pub fn band(index: u32, count: u32, width: u32, height: u32) -> Result<Region, String> {
        if count == 0 || index >= count {
            return Err(format!(
                "--tile {index}/{count}: need 0 <= I < N (parts are numbered from 0)"
            ));
        }
        if count > height {
            return Err(format!(
                "--tile {index}/{count}: the frame has only {height} rows, so at most {height} parts"
            ));
        }
        let row = |i: u32| (u64::from(i) * u64::from(height) / u64::from(count)) as u32;
        Ok(Region {
            x0: 0,
            y0: row(index),
            x1: width,
            y1: row(index + 1),
        })
    }

    /// Why the region does not fit a `width` × `height` frame, or `Ok`.
    pub fn check_inside(&self, width: u32, height: u32) -> Result<(), String> {
        if self.x1 > width || self.y1 > height {
            return Err(format!(
                "crop {},{},{},{} reaches outside the {width}x{height} frame",
                self.x0, self.y0, self.x1, self.y1
            ));
        }
        Ok(())
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }

    /// Whether the region is the whole `width` × `height` frame.
    pub fn is_full(&self, width: u32, height: u32) -> bool {
        *self == Region::full(width, height)
    }
}

/// Parses `I/N` (the `--tile` syntax) into `(I, N)`.
pub fn parse_part(s: &str) -> Result<(u32, u32), String> {
    let err = || format!("expected I/N, e.g. 0/4 (part I of N, from 0), got `{s}`");
    let (i, n) = s.split_once('/').ok_or_else(err)?;
    let i = i.trim().parse::<u32>().map_err(|_| err())?;
    let n = n.trim().parse::<u32>().map_err(|_| err())?;
    Ok((i, n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_cover_every_row_once_and_differ_by_at_most_one_row() {
        for (height, count) in [(10, 3), (7, 7), (64, 4), (1, 1), (100, 9)] {
            let bands: Vec<Region> = (0..count)
                .map(|i| Region::band(i, count, 5, height).unwrap())
                .collect();
            assert_eq!(bands[0].y0, 0);
            assert_eq!(bands[count as usize - 1].y1, height);
            for pair in bands.windows(2) {
                assert_eq!(pair[0].y1, pair[1].y0, "{height} rows / {count}");
            }
            let heights: Vec<u32> = bands.iter().map(Region::height).collect();
            let (lo, hi) = (heights.iter().min().unwrap(), heights.iter().max().unwrap());
            assert!(*lo >= 1 && hi - lo <= 1, "{heights:?}");
        }
    }

    #[test]
    fn bad_parts_and_crops_are_refused() {
        assert!(Region::band(4, 4, 8, 8).unwrap_err().contains("0 <= I < N"));
        assert!(Region::band(0, 9, 8, 8)
            .unwrap_err()
            .contains("only 8 rows"));
        assert!(Region::parse("1,2,1,5").unwrap_err().contains("empty"));
        assert!(Region::parse("1,2,3").is_err());
        assert_eq!(parse_part("2/4"), Ok((2, 4)));
        assert!(parse_part("2").is_err());
        let crop = Region::parse("0,0,9,4").unwrap();
        assert!(crop
            .check_inside(8, 8)
            .unwrap_err()
            .contains("outside the 8x8"));
    }
}
