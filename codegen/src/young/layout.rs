//! The header's counts against the deck's lines.
//!
//! YOUNG reads its deck with Pascal `READ`, so a header that counts one record too many or too
//! few shifts every later record by a few numbers, and the shifted numbers often still read as
//! a mechanism (one simplified constraint too few turns the last one into the time line). The
//! thesis' decks, like every deck written by hand, put the 12 counts on the first line and
//! every record on a line of its own. When a deck's lines have that shape (runs of lines of 7,
//! 5, 4, 8, 14, 20, 21, 3, 4 and 7 numbers in record order, then the time line of 3), the lines
//! say how many records of each size the deck holds, and a header that disagrees with them in
//! one count is refused with both counts. A deck in free format (several records on a line, a
//! record across lines) has no such shape, or disagrees in several counts at once, and is read
//! by the tokens alone.

use super::COUNT_NAMES;

/// Numbers per record, in header order (record kinds 1 to 12).
const SIZES: [usize; 12] = [7, 5, 4, 8, 14, 14, 14, 20, 21, 3, 4, 7];

/// Numbers in the time line.
const TIME: usize = 3;

/// What each count counts, for messages.
const KINDS: [&str; 12] = [
    "bodies",
    "drivers",
    "points of interest",
    "spherical joints",
    "universal joints",
    "revolute joints",
    "cylindrical joints",
    "translational joints",
    "screw joints",
    "simplified constraints",
    "distance constraints",
    "grounded bodies",
];

/// Groups of header counts whose records the lines cannot tell apart: universal, revolute and
/// cylindrical records all have 14 numbers, and points (4) and distance constraints (4), or
/// bodies (7) and grounded bodies (7), meet when every kind between them is absent.
const GROUPS: [&[usize]; 10] = [&[0], &[1], &[2], &[3], &[4, 5, 6], &[7], &[8], &[9], &[10], &[11]];

/// The first disagreement between the header's `counts` and the records the deck's lines hold,
/// as the header field it concerns, a message naming both counts, and the line to point at.
/// `None` when they agree or when the deck's lines do not have the one-record-per-line shape.
pub(super) fn mismatch(deck: &str, counts: &[usize; 12]) -> Option<(&'static str, String, usize)> {
    let lines = numeric_lines(deck);
    let (header, body) = lines.split_first()?;
    let (time, records) = body.split_last()?;
    if header.1 != 12 || time.1 != TIME {
        return None;
    }
    // Maximal runs of lines with the same count: (size, lines, first line number).
    let mut runs: Vec<(usize, usize, usize)> = Vec::new();
    for &(line, size) in records {
        match runs.last_mut() {
            Some(run) if run.0 == size => run.1 += 1,
            _ => runs.push((size, 1, line)),
        }
    }
    // Assign the runs to the groups in record order; a run may cover several groups of its size
    // when every group between them is empty (their counts are then compared as one sum).
    let mut held = [0usize; 10];
    let mut first_line = [0usize; 10];
    let mut g = 0;
    for &(size, count, line) in &runs {
        while g < GROUPS.len() && SIZES[GROUPS[g][0]] != size {
            g += 1;
        }
        if g == GROUPS.len() {
            return None; // Not the one-record-per-line shape.
        }
        held[g] = count;
        first_line[g] = line;
        g += 1;
    }
    // Compare each group's count with the lines, merging a run's trailing same-size groups
    // that the run may also cover (their lines cannot be told apart).
    let counted = |group: &[usize]| group.iter().map(|&k| counts[k]).sum::<usize>();
    let mut found = Vec::new();
    let mut g = 0;
    while g < GROUPS.len() {
        let size = SIZES[GROUPS[g][0]];
        let mut kinds: Vec<usize> = GROUPS[g].to_vec();
        let mut end = g + 1;
        // Later groups of the same size with only empty groups (on the lines) between.
        let mut k = g + 1;
        while k < GROUPS.len() && held[k] == 0 {
            if SIZES[GROUPS[k][0]] == size && held[g] > 0 {
                kinds.extend_from_slice(GROUPS[k]);
                end = k + 1;
            }
            k += 1;
        }
        let header_count = counted(&kinds);
        if header_count != held[g] {
            found.push(message(&kinds, counts, held[g], size, first_line[g], time.0));
        }
        g = end;
    }
    // A count written wrong, or a record line added or lost, changes one group; lines that
    // disagree with several groups are a deck in free format that happens to fit the shape.
    if found.len() == 1 { found.pop() } else { None }
}

/// The message for the kinds `kinds`, which the header counts differently from the `held`
/// lines of `size` numbers the deck has (from `line`, or none: then the time line's `time`).
fn message(
    kinds: &[usize],
    counts: &[usize; 12],
    held: usize,
    size: usize,
    line: usize,
    time: usize,
) -> (&'static str, String, usize) {
    let header: Vec<String> = kinds
        .iter()
        .map(|&k| format!("{} = {} ({})", COUNT_NAMES[k], counts[k], KINDS[k]))
        .collect();
    let total = kinds.iter().map(|&k| counts[k]).sum::<usize>();
    let (place, line) = if held == 0 {
        ("none".to_owned(), time)
    } else {
        (format!("{held}, from line {line}"), line)
    };
    let what = if kinds.len() == 1 {
        format!("{} says {total} such records", header[0])
    } else {
        format!("{} say {total} such records together", header.join(", "))
    };
    // The field to point at: the one count, or the first non-zero one of a group.
    let field =
        kinds.iter().find(|&&k| counts[k] > 0).map_or(COUNT_NAMES[kinds[0]], |&k| COUNT_NAMES[k]);
    (
        field,
        format!(
            "the header's counts disagree with the deck's records: {what} of {size} numbers, \
             but the deck's lines hold {place}; correct the header (each record is on a line of \
             its own)"
        ),
        line,
    )
}

/// (line number, count of numbers) for each non-empty line, up to the first line holding
/// anything but numbers (the free text after the time line), whose leading numbers count.
fn numeric_lines(deck: &str) -> Vec<(usize, usize)> {
    let mut lines = Vec::new();
    for (k, text) in deck.lines().enumerate() {
        let tokens: Vec<&str> = text.split_whitespace().collect();
        let numbers = tokens.iter().take_while(|t| t.parse::<f64>().is_ok()).count();
        if numbers > 0 {
            lines.push((k + 1, numbers));
        }
        if numbers < tokens.len() {
            break;
        }
    }
    lines
}
