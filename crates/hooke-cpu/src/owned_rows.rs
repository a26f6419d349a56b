//! The scatter force pass's order for an irregular mesh: rows of 8 springs whose first ends
//! are one slice's 8 vertices, so the row loads them with vector loads from the axes and only
//! the far ends lane by lane (8 point loads a row instead of 16).
//!
//! A spring's force is the same bits whichever end owns it (`fl(a - b) = -fl(b - a)`), so the
//! owners are free but for one rule of the blocks (`blocks`): a spring whose ends lie in two
//! blocks of [`SPRING_BLOCK`] first ends is owned by the lower one. Owned by the lower
//! vertex, the bench mesh's vertices own 0 to 11 springs, and only 49% of the springs fill
//! rows in which every vertex of a slice has one; [`balance`] moves the ownership of springs
//! within a block so that each slice's vertices own nearly equal numbers (the same for all
//! eight where it can), and [`rows`] lays out each block's slices' full rows, then the
//! springs left over, ordered by first end.
//!
//! **Tails.** Every method sums a vertex's springs in one order, by where the neighbour lies
//! (`Numbering::entries`), so its neighbours later in that order come last. Where each vertex
//! of a slice owns the last `m` of its springs, the slice's first `m` rows are those springs
//! in that order, and scatter's summing takes them as whole rows of forces, in lane order,
//! instead of gathering them lane by lane ([`Tails`]). So a vertex owns its later neighbours'
//! springs where the block rule lets it (their order in place does not follow the numbering),
//! and they are not re-owned.

use hooke_core::Adjacency;

use crate::layout::LANES;
use crate::tables::{SPRING_BLOCK, Slot};

/// Vertices one search for a vertex with a spring to spare visits at most: the searches stay
/// short and their cost linear in the mesh.
const SEARCH_LIMIT: usize = 256;

/// Per slice, how many of its first force rows hold the last springs its vertices sum, in
/// lane order (see the module docs).
pub(crate) type Tails = Vec<u8>;

/// The slots of `ends`' springs (each `[owner, other]`, re-owned in place) in rows of
/// slices' own springs, block by block, and each slice's tail; `vertices` is the padded
/// vertex count, and `later` each (internal) vertex's springs to its neighbours later in
/// place, in the order it sums them.
pub(crate) fn order(
    ends: &mut [[u32; 2]],
    vertices: usize,
    later: &Adjacency,
) -> (Vec<Slot>, Tails) {
    let (tails, fixed) = tails(ends, vertices, later);
    // Who owns a spring changes below, which vertices it joins does not.
    let adjacency = Adjacency::from_springs(vertices, ends);
    balance(ends, &adjacency, &fixed);
    (rows(ends, &adjacency, later, &tails, &fixed), tails)
}

/// Each slice's tail, its springs given to its vertices, and which springs those are.
fn tails(ends: &mut [[u32; 2]], vertices: usize, later: &Adjacency) -> (Tails, Vec<bool>) {
    // A vertex may own the last of its later springs as long as none crosses into a lower
    // block (its other end's block would then own it).
    let ownable = |v: usize| {
        let others = &later.neighbors[later.range(v)];
        let crossing = others
            .iter()
            .rposition(|&w| block_of(w) < block_of(v as u32));
        others.len() - crossing.map_or(0, |at| at + 1)
    };
    let tails: Tails = (0..vertices / LANES)
        .map(|s| {
            let m = (s * LANES..(s + 1) * LANES).map(ownable).min().unwrap_or(0);
            m.min(u8::MAX as usize) as u8
        })
        .collect();
    let mut fixed = vec![false; ends.len()];
    for (s, &m) in tails.iter().enumerate() {
        for v in s * LANES..(s + 1) * LANES {
            let range = later.range(v);
            for e in range.end - usize::from(m)..range.end {
                let spring = later.springs[e] as usize;
                ends[spring] = [v as u32, later.neighbors[e]];
                fixed[spring] = true;
            }
        }
    }
    (tails, fixed)
}

fn block_of(v: u32) -> u32 {
    v / SPRING_BLOCK
}

/// Whether a spring's ends share a block, so that either may own it.
fn is_free([a, b]: [u32; 2]) -> bool {
    block_of(a) == block_of(b)
}

/// Re-owns springs within blocks so that each slice's vertices own at least `m` springs
/// each, `m` as high as the searches find: first half their valence (rounded down) for the
/// slice's lowest, then one more where every vertex of the slice finds one. A vertex short of
/// its target takes a spring from a neighbour with one to spare, or along a path of owners
/// (each passes one on), so nobody falls below their own target.
fn balance(ends: &mut [[u32; 2]], adjacency: &Adjacency, fixed: &[bool]) {
    let vertices = adjacency.offsets.len() - 1;
    let springs_at = |v: usize| adjacency.range(v).map(|e| adjacency.springs[e] as usize);
    let mut owned = vec![0u32; vertices];
    for e in ends.iter() {
        owned[e[0] as usize] += 1;
    }
    // What a vertex may own: the springs within its block, and those across blocks it owns.
    let most = |v: usize| {
        let may_own =
            springs_at(v).filter(|&s| (is_free(ends[s]) && !fixed[s]) || ends[s][0] as usize == v);
        (may_own.count() as u32).min(adjacency.valence(v) / 2)
    };
    let mut target = vec![0u32; vertices];
    for (s, lanes) in target.chunks_mut(LANES).enumerate() {
        let m = (s * LANES..(s + 1) * LANES).map(most).min().unwrap_or(0);
        lanes.fill(m);
    }
    let mut search = Search::new(vertices);
    for v in 0..vertices as u32 {
        while owned[v as usize] < target[v as usize] {
            if !search.take_one(v, ends, adjacency, fixed, &mut owned, &target) {
                break;
            }
        }
    }
    // One more each where a whole slice finds it.
    for s in 0..vertices / LANES {
        let lanes = s * LANES..(s + 1) * LANES;
        if lanes.clone().any(|v| adjacency.valence(v) == 0) {
            continue;
        }
        let raised = target[s * LANES] + 1;
        target[lanes.clone()].fill(raised);
        let all = lanes.clone().all(|v| {
            owned[v] >= raised
                || search.take_one(v as u32, ends, adjacency, fixed, &mut owned, &target)
        });
        if !all {
            target[lanes].fill(raised - 1);
        }
    }
}

/// Breadth-first searches from a vertex short of springs back along the springs owned into
/// it, for an owner with one to spare.
struct Search {
    /// The search that last reached each vertex, and from where, by which spring.
    seen: Vec<u32>,
    from: Vec<(u32, u32)>,
    epoch: u32,
    queue: Vec<u32>,
}

impl Search {
    fn new(vertices: usize) -> Self {
        Self {
            seen: vec![0; vertices],
            from: vec![(0, 0); vertices],
            epoch: 0,
            queue: Vec::with_capacity(SEARCH_LIMIT),
        }
    }

    /// Gives `v` one more spring, taken along a path of owners from one that owns more than
    /// its target; false if the search finds none.
    fn take_one(
        &mut self,
        v: u32,
        ends: &mut [[u32; 2]],
        adjacency: &Adjacency,
        fixed: &[bool],
        owned: &mut [u32],
        target: &[u32],
    ) -> bool {
        self.epoch += 1;
        self.queue.clear();
        self.queue.push(v);
        self.seen[v as usize] = self.epoch;
        let mut head = 0;
        while head < self.queue.len() {
            let u = self.queue[head];
            head += 1;
            for &s in &adjacency.springs[adjacency.range(u as usize)] {
                let [owner, other] = ends[s as usize];
                if other != u
                    || !is_free([owner, other])
                    || fixed[s as usize]
                    || self.seen[owner as usize] == self.epoch
                {
                    continue;
                }
                self.seen[owner as usize] = self.epoch;
                self.from[owner as usize] = (u, s);
                if owned[owner as usize] > target[owner as usize] {
                    // Each spring on the path passes to the vertex it led from.
                    let mut x = owner;
                    while x != v {
                        let (u, s) = self.from[x as usize];
                        ends[s as usize] = [u, x];
                        x = u;
                    }
                    owned[owner as usize] -= 1;
                    owned[v as usize] += 1;
                    return true;
                }
                if self.queue.len() < SEARCH_LIMIT {
                    self.queue.push(owner);
                }
            }
        }
        false
    }
}

/// Block by block: for each slice, its tail's rows (row `r` holding each vertex's `r`-th of
/// its last `tail` springs), then as many rows as its vertices all own other springs (row `k`
/// holding each vertex's `k`-th, by far end), then the block's springs left over by first end
/// and far end, padded to a whole row so that the next block's rows start whole.
fn rows(
    ends: &[[u32; 2]],
    adjacency: &Adjacency,
    later: &Adjacency,
    tails: &Tails,
    fixed: &[bool],
) -> Vec<Slot> {
    let vertices = adjacency.offsets.len() - 1;
    // Each vertex's own springs but its tail's, by far end.
    let mut start = vec![0usize];
    let mut owned = Vec::with_capacity(ends.len());
    for v in 0..vertices {
        let first = owned.len();
        let springs = adjacency.springs[adjacency.range(v)].iter();
        owned.extend(springs.filter(|&&s| ends[s as usize][0] as usize == v && !fixed[s as usize]));
        owned[first..].sort_by_key(|&s| ends[s as usize][1]);
        start.push(owned.len());
    }
    let springs_of = |v: usize| &owned[start[v]..start[v + 1]];
    let mut slots = Vec::with_capacity(ends.len() + ends.len() / 8);
    let block = SPRING_BLOCK as usize;
    for first in (0..vertices).step_by(block) {
        let block_vertices = first..(first + block).min(vertices);
        let mut full = vec![0usize; block_vertices.len()];
        for s in block_vertices.clone().step_by(LANES) {
            let lanes = s..s + LANES;
            let tail = usize::from(tails[s / LANES]);
            for r in 0..tail {
                let entry = |v: usize| later.range(v).end - tail + r;
                slots.extend(lanes.clone().map(|v| Slot::Spring(later.springs[entry(v)])));
            }
            let m = lanes
                .clone()
                .map(|v| springs_of(v).len())
                .min()
                .unwrap_or(0);
            for k in 0..m {
                slots.extend(lanes.clone().map(|v| Slot::Spring(springs_of(v)[k])));
            }
            full[s - first..s - first + LANES].fill(m);
        }
        let before = slots.len();
        for v in block_vertices.clone() {
            let rest = &springs_of(v)[full[v - first]..];
            slots.extend(rest.iter().map(|&s| Slot::Spring(s)));
        }
        if slots.len() > before {
            let last = block_vertices.end as u32 - 1;
            while !slots.len().is_multiple_of(LANES) {
                slots.push(Slot::Padding(last));
            }
        }
    }
    slots
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strip of triangles, vertex v joined to v + 1 and v + 2 (springs `2v` and `2v + 1`),
    /// and no springs later in place, or those two, in that order.
    fn strip(n: u32, with_later: bool) -> (Vec<[u32; 2]>, Adjacency) {
        let ends: Vec<[u32; 2]> = (0..n - 2).flat_map(|v| [[v, v + 1], [v, v + 2]]).collect();
        let mut later = Adjacency {
            offsets: vec![0],
            neighbors: Vec::new(),
            springs: Vec::new(),
        };
        for v in 0..n {
            if with_later {
                for d in (1..=2).filter(|d| v + d < n) {
                    later.neighbors.push(v + d);
                    later.springs.push(2 * v + d - 1);
                }
            }
            later.offsets.push(later.springs.len() as u32);
        }
        (ends, later)
    }

    /// Every spring keeps its two ends, and one crossing blocks stays with the lower.
    #[test]
    fn balancing_only_re_owns_springs_within_blocks() {
        let n = 2 * SPRING_BLOCK;
        let (mut ends, later) = strip(n, false);
        let before = ends.clone();
        let (slots, tails) = order(&mut ends, n as usize, &later);
        assert!(tails.iter().all(|&t| t == 0));
        for (e, b) in ends.iter().zip(&before) {
            let (mut e, mut b) = (*e, *b);
            if block_of(b[0]) != block_of(b[1]) {
                assert_eq!(e, b, "a spring across blocks changed owner");
            }
            e.sort_unstable();
            b.sort_unstable();
            assert_eq!(e, b);
        }
        let mut seen: Vec<u32> = slots
            .iter()
            .filter_map(|s| match s {
                Slot::Spring(s) => Some(*s),
                Slot::Padding(_) => None,
            })
            .collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..ends.len() as u32).collect::<Vec<_>>());
        // Every vertex of the strip has valence 4 but at its ends, so owns 2 in full rows.
        let full_rows = slots
            .chunks(LANES)
            .filter(|row| {
                let firsts: Vec<u32> = row
                    .iter()
                    .map(|s| match s {
                        Slot::Spring(s) => ends[*s as usize][0],
                        Slot::Padding(v) => *v,
                    })
                    .collect();
                firsts[0].is_multiple_of(LANES as u32)
                    && firsts
                        .iter()
                        .enumerate()
                        .all(|(k, a)| *a == firsts[0] + k as u32)
            })
            .count();
        assert!(
            full_rows * LANES * 10 >= ends.len() * 9,
            "{full_rows} full rows"
        );
    }

    /// Each slice's vertices own their later springs, laid out as its first rows in lane
    /// order, where no later spring reaches into a lower block (none does in a strip).
    #[test]
    fn tails_are_each_slices_later_springs_in_lane_order() {
        let n = 2 * SPRING_BLOCK;
        let (mut ends, later) = strip(n, true);
        let (slots, tails) = order(&mut ends, n as usize, &later);
        let slices = n as usize / LANES;
        // The last vertex has no later neighbour.
        assert!(tails[..slices - 1].iter().all(|&t| t == 2), "{tails:?}");
        assert_eq!(tails[slices - 1], 0);
        let mut row = 0;
        for (s, &tail) in tails[..slices - 1].iter().enumerate() {
            // The slice's rows start where its lanes' first spring is.
            while !matches!(slots[row * LANES], Slot::Spring(x) if ends[x as usize][0] as usize == s * LANES)
            {
                row += 1;
            }
            for r in 0..usize::from(tail) {
                for lane in 0..LANES {
                    let v = (s * LANES + lane) as u32;
                    let spring = 2 * v + r as u32;
                    assert_eq!(slots[(row + r) * LANES + lane], Slot::Spring(spring));
                    assert_eq!(ends[spring as usize], [v, v + 1 + r as u32]);
                }
            }
        }
    }
}
