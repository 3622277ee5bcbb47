//! Names compared loosely: the suggestions of a 404 ("did you mean …") and
//! the look-alike check that keeps a registered robot from passing for a
//! built-in one. Owns the normalisation (lowercase; `-`, `_` and spaces
//! removed) and a per-snapshot index built at most once per registry change
//! (on the first lookup after it), so that one lookup costs a hash probe plus
//! at most [`MAX_COMPARED`] bounded edit distances, however many robots there
//! are. Depends on nothing but `std`; the registry owns when it is rebuilt.

use std::collections::HashMap;

/// Most names one suggestion lookup compares by edit distance (after the
/// exact normalised match and the length window); beyond it, the names of
/// nearest length are compared first and the rest are not.
pub const MAX_COMPARED: usize = 128;

/// Longest name (normalised, characters) suggestions are looked up for.
const MAX_QUERY_CHARS: usize = 64;

/// Suggestions answered at most.
const MAX_SUGGESTIONS: usize = 3;

/// Lowercase, with `-`, `_` and spaces removed (`Puma-560` → `puma560`).
pub fn normalise(name: &str) -> String {
    name.chars()
        .filter(|c| !matches!(c, '-' | '_' | ' '))
        .flat_map(char::to_lowercase)
        .collect()
}

/// One robot name with its normalised form and that form's letter counts.
#[derive(Debug)]
struct Known {
    norm: Vec<char>,
    bag: Bag,
    name: String,
}

/// How often each of `a`–`z`, `0`–`9` and anything else occurs in a name
/// (saturating): the bag distance of two bags is a lower bound of the edit
/// distance, and costs 37 steps instead of a table of |a|·|b|.
type Bag = [u8; 37];

fn bag(chars: &[char]) -> Bag {
    let mut b = [0u8; 37];
    for c in chars {
        let k = match c {
            'a'..='z' => *c as usize - 'a' as usize,
            '0'..='9' => 26 + (*c as usize - '0' as usize),
            _ => 36,
        };
        if let Some(n) = b.get_mut(k) {
            *n = n.saturating_add(1);
        }
    }
    b
}

/// `max(|a − b|, |b − a|)` of two bags: at most the edit distance.
fn bag_distance(a: &Bag, b: &Bag) -> usize {
    let (mut more, mut fewer) = (0usize, 0usize);
    for (x, y) in a.iter().zip(b) {
        if x > y {
            more += usize::from(x - y);
        } else {
            fewer += usize::from(y - x);
        }
    }
    more.max(fewer)
}

/// Every name of one registry snapshot, ready for loose lookups.
#[derive(Debug, Default)]
pub struct NameIndex {
    /// Sorted by normalised length, then name.
    by_len: Vec<Known>,
    /// Normalised form → the names that have it (sorted).
    exact: HashMap<String, Vec<String>>,
    /// Normalised form of every built-in → its name.
    builtins: HashMap<String, String>,
}

impl NameIndex {
    /// The index of `names`, each with whether it is a built-in.
    pub fn build<'a>(names: impl Iterator<Item = (&'a str, bool)>) -> NameIndex {
        let mut index = NameIndex::default();
        for (name, builtin) in names {
            let norm = normalise(name);
            if builtin {
                index.builtins.insert(norm.clone(), name.to_string());
            }
            index
                .exact
                .entry(norm.clone())
                .or_default()
                .push(name.to_string());
            let chars: Vec<char> = norm.chars().collect();
            index.by_len.push(Known {
                bag: bag(&chars),
                norm: chars,
                name: name.to_string(),
            });
        }
        index
            .by_len
            .sort_by(|a, b| (a.norm.len(), &a.name).cmp(&(b.norm.len(), &b.name)));
        index.exact.values_mut().for_each(|v| v.sort());
        index
    }

    /// The built-in that `name` would pass for (equal once normalised), if
    /// any, unless `name` is that built-in itself.
    pub fn builtin_lookalike(&self, name: &str) -> Option<&str> {
        self.builtins
            .get(&normalise(name))
            .map(String::as_str)
            .filter(|b| *b != name)
    }

    /// Up to three names close to `name`, best first: equal once normalised,
    /// then within an edit distance of a third of its length (at least 2) of
    /// the normalised forms. Compares at most [`MAX_COMPARED`] names.
    pub fn nearest(&self, name: &str) -> Vec<String> {
        let wanted: Vec<char> = normalise(name).chars().collect();
        if wanted.len() > MAX_QUERY_CHARS {
            return Vec::new();
        }
        let budget = (wanted.len() / 3).max(2);
        let exact = self
            .exact
            .get(&wanted.iter().collect::<String>())
            .map_or(&[][..], Vec::as_slice);
        let mut scored: Vec<(usize, &str)> = exact
            .iter()
            .take(MAX_SUGGESTIONS)
            .map(|n| (0, n.as_str()))
            .collect();
        if scored.len() < MAX_SUGGESTIONS {
            let wanted_bag = bag(&wanted);
            for k in self.window(wanted.len(), budget) {
                if bag_distance(&wanted_bag, &k.bag) > budget {
                    continue;
                }
                if let Some(d) = bounded_levenshtein(&wanted, &k.norm, budget)
                    && d > 0
                {
                    scored.push((d, &k.name));
                }
            }
        }
        scored.sort();
        scored
            .into_iter()
            .take(MAX_SUGGESTIONS)
            .map(|(_, n)| n.to_string())
            .collect()
    }

    /// The names whose normalised length is within `budget` of `len`, nearest
    /// length first, at most [`MAX_COMPARED`] of them.
    fn window(&self, len: usize, budget: usize) -> impl Iterator<Item = &Known> {
        let lo = self
            .by_len
            .partition_point(|k| k.norm.len() < len.saturating_sub(budget));
        let hi = self
            .by_len
            .partition_point(|k| k.norm.len() <= len + budget);
        let mut window: Vec<&Known> = self.by_len.get(lo..hi).unwrap_or_default().iter().collect();
        if window.len() > MAX_COMPARED {
            window.sort_by_key(|k| k.norm.len().abs_diff(len));
            window.truncate(MAX_COMPARED);
        }
        window.into_iter()
    }
}

/// The Levenshtein distance of `a` and `b` if it is at most `max`; `None`
/// as soon as it is known to be larger (every cell of a row above `max`).
/// Time O(|a|·|b|) at worst, usually far less; memory one row.
fn bounded_levenshtein(a: &[char], b: &[char], max: usize) -> Option<usize> {
    if a.len().abs_diff(b.len()) > max {
        return None;
    }
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.iter().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        let mut row_min = row[0];
        for (j, cb) in b.iter().enumerate() {
            let substitute = diagonal + usize::from(ca != cb);
            diagonal = row[j + 1];
            row[j + 1] = substitute.min(row[j] + 1).min(diagonal + 1);
            row_min = row_min.min(row[j + 1]);
        }
        if row_min > max {
            return None;
        }
    }
    row.last().copied().filter(|&d| d <= max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn index(names: &[&str], builtins: &[&str]) -> NameIndex {
        NameIndex::build(
            names
                .iter()
                .map(|n| (*n, false))
                .chain(builtins.iter().map(|n| (*n, true))),
        )
    }

    #[test]
    fn bounded_distance_agrees_with_strsim_within_the_bound() {
        let words = [
            "", "a", "puma560", "puma-560", "pmua560", "ur5e", "ur10e", "kitten", "sitting",
        ];
        for a in words {
            for b in words {
                let (na, nb) = (normalise(a), normalise(b));
                let full = strsim::levenshtein(&na, &nb);
                let ca: Vec<char> = na.chars().collect();
                let cb: Vec<char> = nb.chars().collect();
                for max in 0..6 {
                    let want = (full <= max).then_some(full);
                    assert_eq!(bounded_levenshtein(&ca, &cb, max), want, "{a} {b} {max}");
                }
                assert!(bag_distance(&bag(&ca), &bag(&cb)) <= full, "{a} {b}");
            }
        }
    }

    #[test]
    fn suggestions_put_normalised_equals_first_then_near_names() {
        let i = index(&["planar2", "planar3", "ur5e", "my-robot"], &["puma560"]);
        assert_eq!(i.nearest("Puma_560"), ["puma560"]);
        assert_eq!(i.nearest("planar"), ["planar2", "planar3"]);
        assert_eq!(i.nearest("MyRobot"), ["my-robot"]);
        assert!(i.nearest("zzzzzzzzzzzz").is_empty());
        assert!(i.nearest(&"x".repeat(65)).is_empty());
    }

    #[test]
    fn an_exact_match_is_found_beyond_the_comparison_cap() {
        let many: Vec<String> = (0..2 * MAX_COMPARED)
            .map(|k| format!("bot{k:05}"))
            .collect();
        let mut names: Vec<&str> = many.iter().map(String::as_str).collect();
        names.push("bot-01999");
        let i = index(&names, &[]);
        assert_eq!(i.nearest("BOT01999")[0], "bot-01999");
        assert_eq!(i.nearest("bot00007").len(), MAX_SUGGESTIONS);
    }

    #[test]
    fn lookalikes_of_builtins_are_named_but_the_builtin_itself_is_not() {
        let i = index(&[], &["puma560", "ur5e"]);
        for n in ["puma-560", "puma_560", "PUMA560", "pu-ma-5-6-0", "puma 560"] {
            assert_eq!(i.builtin_lookalike(n), Some("puma560"), "{n}");
        }
        assert_eq!(i.builtin_lookalike("puma560"), None);
        assert_eq!(i.builtin_lookalike("puma561"), None);
        assert_eq!(i.builtin_lookalike("ur-5e"), Some("ur5e"));
    }
}
