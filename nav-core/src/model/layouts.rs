//! State layouts: which blocks a filter carries, in order ([`Layout`]), and the layouts of the
//! source's models.

use super::*;

/// Errors of a layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LayoutError {
    /// The layout's total dimension differs from the filter's const N.
    DimensionMismatch {
        /// Sum of the block dimensions.
        layout: usize,
        /// The filter's N.
        filter: usize,
    },
    /// The first block is not [`Block::Core`], or Core appears twice.
    CoreNotFirst,
    /// Two blocks of the same kind.
    DuplicateKind,
    /// More than [`MAX_BLOCKS`] blocks were given to [`Layout::new`].
    TooManyBlocks,
}

impl core::fmt::Display for LayoutError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::DimensionMismatch { layout, filter } => write!(
                f,
                "layout: blocks add up to {layout} states but the filter has N = {filter}"
            ),
            Self::CoreNotFirst => {
                f.write_str("layout: the first (and only the first) block must be Core")
            }
            Self::DuplicateKind => f.write_str("layout: two blocks of the same kind"),
            Self::TooManyBlocks => write!(f, "layout: more than {MAX_BLOCKS} blocks"),
        }
    }
}

/// An ordered list of blocks, built at compile time:
/// `const L: Layout = Layout::new(&[Block::Core, ...]); type F = Filter<f32, { L.dim() }>;`
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    blocks: [Block; MAX_BLOCKS],
    len: usize,
    overflow: bool,
}

impl Layout {
    /// A layout of `blocks` in order (at most [`MAX_BLOCKS`]; more is reported by
    /// [`Layout::validate`]).
    #[allow(clippy::indexing_slicing)] // both indices bounded by the loop condition
    pub const fn new(blocks: &[Block]) -> Self {
        let mut out = [Block::Core; MAX_BLOCKS];
        let mut i = 0;
        while i < blocks.len() && i < MAX_BLOCKS {
            out[i] = blocks[i];
            i += 1;
        }
        Self {
            blocks: out,
            len: i,
            overflow: blocks.len() > MAX_BLOCKS,
        }
    }

    /// Total number of error states.
    #[allow(clippy::indexing_slicing)] // index bounded by the loop condition
    pub const fn dim(&self) -> usize {
        let mut n = 0;
        let mut i = 0;
        while i < self.len && i < MAX_BLOCKS {
            n += self.blocks[i].dim();
            i += 1;
        }
        n
    }

    /// This layout with `block` appended (compile-time composition: base model + effects,
    /// e.g. `LAYOUT_NBK.with(Block::LeverArm)`). Appending beyond [`MAX_BLOCKS`] is reported
    /// by [`Layout::validate`]; duplicates too.
    #[allow(clippy::indexing_slicing)] // index checked against MAX_BLOCKS
    pub const fn with(self, block: Block) -> Self {
        let mut out = self;
        if out.len < MAX_BLOCKS {
            out.blocks[out.len] = block;
            out.len += 1;
        } else {
            out.overflow = true;
        }
        out
    }

    /// Whether the layout has a block of `kind`.
    pub fn contains(&self, kind: BlockKind) -> bool {
        self.blocks().iter().any(|b| b.kind() == kind)
    }

    /// Number of blocks.
    pub const fn len(&self) -> usize {
        self.len
    }

    /// Whether the layout has no block at all.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The blocks in order.
    pub fn blocks(&self) -> &[Block] {
        self.blocks.get(..self.len).unwrap_or(&[])
    }

    /// The blocks with their state offsets.
    pub fn iter(&self) -> impl Iterator<Item = (usize, Block)> + '_ {
        self.blocks().iter().scan(0usize, |off, b| {
            let o = *off;
            *off += b.dim();
            Some((o, *b))
        })
    }

    /// The block of `kind` and its state offset.
    pub fn find(&self, kind: BlockKind) -> Option<(usize, Block)> {
        self.iter().find(|(_, b)| b.kind() == kind)
    }

    /// Checks the layout for a filter of `n` states.
    pub fn validate(&self, n: usize) -> Result<(), LayoutError> {
        if self.overflow {
            return Err(LayoutError::TooManyBlocks);
        }
        let bl = self.blocks();
        if bl.first() != Some(&Block::Core) || bl.iter().skip(1).any(|b| *b == Block::Core) {
            return Err(LayoutError::CoreNotFirst);
        }
        for (i, a) in bl.iter().enumerate() {
            if bl.iter().skip(i + 1).any(|b| b.kind() == a.kind()) {
                return Err(LayoutError::DuplicateKind);
            }
        }
        if self.dim() != n {
            return Err(LayoutError::DimensionMismatch {
                layout: self.dim(),
                filter: n,
            });
        }
        Ok(())
    }
}

/// The source's classical N model: core + constant gyro bias + constant accelerometer bias
/// (15 states).
pub const LAYOUT_N: Layout = Layout::new(&[
    Block::Core,
    Block::GyroBias(BiasModel::Constant),
    Block::AccelBias(BiasModel::Constant),
]);

/// The source's detailed NBK model with separate Gauss-Markov and random-walk accelerometer
/// bias states (DESIGN.md's exact form): 18 states.
pub const LAYOUT_NBK: Layout = Layout::new(&[
    Block::Core,
    Block::GyroBias(BiasModel::Constant),
    Block::AccelBias(BiasModel::GaussMarkovRandomWalk),
]);

/// The source's NBK model as printed: one decaying accelerometer bias state driven by both
/// S_B and S_K: 15 states.
pub const LAYOUT_NBK_SINGLE: Layout = Layout::new(&[
    Block::Core,
    Block::GyroBias(BiasModel::Constant),
    Block::AccelBias(BiasModel::SingleStateGmRw),
]);

/// KF-GINS's 21-state model: Gauss-Markov gyro and accelerometer biases and scale factors.
pub const LAYOUT_KF_GINS: Layout = Layout::new(&[
    Block::Core,
    Block::GyroBias(BiasModel::GaussMarkov),
    Block::AccelBias(BiasModel::GaussMarkov),
    Block::GyroScaleFactor,
    Block::AccelScaleFactor,
]);

/// A filter model fixed at compile time: the state layout as part of a type, so that a
/// navigator of this model is given its layout once (the type) and its dimension follows from
/// it. [`crate::navigator::Navigator::for_model`] checks `LAYOUT.dim() == N` when it is
/// compiled. Layouts built at run time (effect blocks added by a configuration) go through
/// [`crate::navigator::Navigator::new`] and its run-time check instead.
pub trait StateModel {
    /// The state layout.
    const LAYOUT: Layout;
    /// The number of error states, `LAYOUT.dim()` (the `N` of a navigator of this model).
    const DIM: usize = Self::LAYOUT.dim();
}

/// The classical N model ([`LAYOUT_N`], 15 states).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ModelN;
impl StateModel for ModelN {
    const LAYOUT: Layout = LAYOUT_N;
}

/// The NBK model ([`LAYOUT_NBK`], 18 states).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ModelNbk;
impl StateModel for ModelNbk {
    const LAYOUT: Layout = LAYOUT_NBK;
}

/// The NBK model as printed ([`LAYOUT_NBK_SINGLE`], 15 states).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ModelNbkSingle;
impl StateModel for ModelNbkSingle {
    const LAYOUT: Layout = LAYOUT_NBK_SINGLE;
}

/// KF-GINS's model ([`LAYOUT_KF_GINS`], 21 states).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ModelKfGins;
impl StateModel for ModelKfGins {
    const LAYOUT: Layout = LAYOUT_KF_GINS;
}

impl core::error::Error for LayoutError {}
