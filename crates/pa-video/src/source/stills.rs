//! A folder of stills as a source.

use std::path::{Path, PathBuf};

use super::{file_name, list_stills, Next, Pixels, Source, SourceFrame};
use crate::VideoError;

/// Stills in order (a folder's in natural order, [`super::list_stills`]): still `i` is frame
/// `i`. Every still starts a new sequence; its pixels are [`Pixels::Still`], read by the
/// caller only when the still is to be processed.
#[derive(Debug, Clone)]
pub struct StillsSource {
    stills: Vec<PathBuf>,
    next: usize,
}

impl StillsSource {
    /// The stills of `dir` in natural order ([`VideoError::NoStills`] when there are none).
    pub fn open(dir: &Path) -> Result<Self, VideoError> {
        Ok(Self::new(list_stills(dir)?))
    }

    /// These stills, in this order.
    pub fn new(stills: Vec<PathBuf>) -> Self {
        Self { stills, next: 0 }
    }

    /// The stills, in order.
    pub fn paths(&self) -> &[PathBuf] {
        &self.stills
    }

    /// The file name of still `index` (what logs call it).
    pub fn name(&self, index: usize) -> Option<String> {
        self.stills.get(index).map(|p| file_name(p))
    }

    /// Still `index` as a frame, without moving the source (for random access).
    pub fn frame(&self, index: usize) -> Option<SourceFrame> {
        let path = self.stills.get(index)?;
        Some(SourceFrame {
            index,
            name: file_name(path),
            starts_sequence: true,
            pixels: Pixels::Still(path.clone()),
        })
    }
}

impl Source for StillsSource {
    fn frame_count(&self) -> Option<usize> {
        Some(self.stills.len())
    }

    fn next(&mut self) -> Result<Next, VideoError> {
        let Some(frame) = self.frame(self.next) else {
            return Ok(Next::End);
        };
        self.next += 1;
        Ok(Next::Frame(frame))
    }

    fn describe(&self) -> String {
        format!("{} still(s)", self.stills.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_still_is_a_frame_that_starts_a_sequence() {
        let mut s = StillsSource::new(vec!["a/s1.png".into(), "a/s2.png".into()]);
        assert_eq!(s.frame_count(), Some(2));
        assert_eq!(s.name(1).as_deref(), Some("s2.png"));
        for i in 0..2 {
            let Ok(Next::Frame(f)) = s.next() else {
                panic!("frame {i}");
            };
            assert_eq!((f.index, f.starts_sequence), (i, true));
            assert!(matches!(f.pixels, Pixels::Still(ref p) if p == &s.paths()[i]));
        }
        assert!(matches!(s.next(), Ok(Next::End)));
        assert!(s.frame(2).is_none());
    }
}
