//! Which solved values read a changed input, and what those values read:
//! the texels of a page an edit can change through the stitch's solve, and
//! the texels a rebake must know to solve them.
//!
//! In: a system's rows (their unknowns and fixed texels), its unknowns'
//! texels and components, per texel whether its inputs changed (the
//! seeds: its value before the solve, or a row through its cell), and how
//! many rows a solved value reads beyond its own ([`Solver::reach`]). Out:
//! [`Reads`].
//!
//! [`Solver::reach`]: super::solve::Solver::reach

use super::solver::Row;

/// How far a system's unknowns lie from the seeds.
#[derive(Clone, Debug, Default)]
pub struct Reads {
    /// Per unknown, the rows between it and a seed (0: it is one, or a row
    /// holding it has a tap on one; `u32::MAX`: farther than twice the
    /// reach and one, or in another component).
    pub depth: Vec<u32>,
    /// The fixed texels of the rows within twice the reach of a seed: what
    /// the unknowns within the reach read besides the unknowns.
    pub fixed: Vec<u32>,
    /// The rows a solved value reads beyond its own: an unknown within it
    /// of a seed may change (0 under conjugate gradients, whose values read
    /// whole components, every unknown of a touched one at depth 0).
    pub reach: u32,
}

/// How far each unknown lies from the seeds: breadth first over the rows,
/// twice `reach` and one out (a value within `reach` of a seed reads the
/// unknowns within `reach` of itself); with `reach` `None` (the solve reads
/// whole components), every unknown of a component holding a seed is 0.
/// Past `reach`, the search does not go on from an unknown whose value is
/// not `known`: in a bake of part of a page the structure beyond it is not
/// the page's (cells not known count as steps), and what it reads is found
/// once it is known.
pub(super) fn reached(
    rows: &[Row],
    texel_of: &[u32],
    component: &[u32],
    seeds: &[bool],
    reach: Option<usize>,
    known: &[bool],
) -> Reads {
    let n = texel_of.len();
    let seed = |t: u32| seeds.get(t as usize).copied().unwrap_or(false);
    let mut depth = vec![u32::MAX; n];
    for (u, &t) in texel_of.iter().enumerate() {
        if seed(t) {
            depth[u] = 0;
        }
    }
    let mut crossed = vec![false; rows.len()];
    for (r, row) in rows.iter().enumerate() {
        let free = row.free.iter().any(|&(u, _)| seed(texel_of[u as usize]));
        if free || row.fixed.iter().any(|&(t, _)| seed(t)) {
            row.free.iter().for_each(|&(u, _)| depth[u as usize] = 0);
            crossed[r] = true;
        }
    }
    let fixed_of = |crossed: &[bool]| {
        (rows.iter().zip(crossed).filter(|&(_, &c)| c))
            .flat_map(|(row, _)| row.fixed.iter().map(|&(t, _)| t))
            .collect()
    };
    let Some(reach) = reach else {
        let count = component.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut touched = vec![false; count];
        for (u, &c) in component.iter().enumerate() {
            touched[c as usize] |= depth[u] == 0;
        }
        for (u, &c) in component.iter().enumerate() {
            depth[u] = if touched[c as usize] { 0 } else { u32::MAX };
        }
        for (r, row) in rows.iter().enumerate() {
            crossed[r] = touched[component[row.free[0].0 as usize] as usize];
        }
        let fixed = fixed_of(&crossed);
        return Reads {
            depth,
            fixed,
            reach: 0,
        };
    };
    // Per unknown, its rows (compressed: `first[u]..first[u + 1]`).
    let mut first = vec![0u32; n + 1];
    for row in rows {
        row.free
            .iter()
            .for_each(|&(u, _)| first[u as usize + 1] += 1);
    }
    for u in 0..n {
        first[u + 1] += first[u];
    }
    let mut at = first.clone();
    let mut of = vec![0u32; first[n] as usize];
    for (r, row) in rows.iter().enumerate() {
        for &(u, _) in &row.free {
            of[at[u as usize] as usize] = r as u32;
            at[u as usize] += 1;
        }
    }
    // Breadth first; a row once crossed is done.
    let mut frontier: Vec<u32> = (0..n as u32).filter(|&u| depth[u as usize] == 0).collect();
    for hop in 1..=2 * reach as u32 + 1 {
        let mut next = Vec::new();
        for &u in frontier
            .iter()
            .filter(|&&u| hop <= reach as u32 + 1 || known[u as usize])
        {
            for &r in &of[first[u as usize] as usize..first[u as usize + 1] as usize] {
                if std::mem::replace(&mut crossed[r as usize], true) {
                    continue;
                }
                for &(v, _) in &rows[r as usize].free {
                    if depth[v as usize] == u32::MAX {
                        depth[v as usize] = hop;
                        next.push(v);
                    }
                }
            }
        }
        if next.is_empty() {
            break;
        }
        frontier = next;
    }
    let fixed = fixed_of(&crossed);
    Reads {
        depth,
        fixed,
        reach: reach as u32,
    }
}
