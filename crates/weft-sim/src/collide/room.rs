//! How much one step's detection may hold: contacts and candidate pairs of primitives, each
//! within a share of the memory allowed. Shared by the collider detector and the detection
//! between solids, which both stop at their room rather than grow past it.

/// Bytes one contact takes at most over a step: the contact (176), its detection key, and
/// the contact step's state for it (its active entry, ADMM's vectors, the impulses kept for
/// the next round, the blocks it adds between solids): about 700 from the types' sizes,
/// rounded up.
pub const CONTACT_BYTES: u64 = 1024;

/// Bytes a candidate pair of primitives takes in the broad phase between solids (the trees'
/// pair, the filtered candidate and the narrow phase's entry: about 100), rounded up.
pub const PAIR_BYTES: u64 = 128;

/// How many contacts, and candidate pairs of primitives between solids, one step's detection
/// may hold: a quarter of the memory allowed each (a list may hold twice its length while it
/// grows). A contact band that takes in most of a scene (a thickness in metres where
/// millimetres were meant) would otherwise grow these lists as the product of the primitive
/// counts; detection stops at the room instead, and the step fails naming the band.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Room {
    /// Contacts.
    pub contacts: usize,
    /// Candidate pairs of primitives.
    pub pairs: usize,
}

impl Room {
    /// The room within `max_bytes` (`None`: unbounded).
    pub fn within(max_bytes: Option<u64>) -> Self {
        let of = |each: u64| {
            max_bytes.map_or(usize::MAX, |m| {
                usize::try_from(m / 4 / each).unwrap_or(usize::MAX)
            })
        };
        Room {
            contacts: of(CONTACT_BYTES),
            pairs: of(PAIR_BYTES),
        }
    }
}
