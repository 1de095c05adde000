//! What the sink's status lines say is wrong: the warnings `hoploc monitor` and `hoploc replay`
//! print when a status line's counters (`loc_proto::sink_line`, `SinkLine::Status`) moved since
//! the one before, each with what to check. The README's "What goes wrong and what the nodes
//! say" lists the same cases.

use loc_proto::sink_line::{SinkLine, STATUS_FIELDS};

/// The warnings of status line `now` after `before` (the previous status line of the same
/// sink, `None` for the first: then every counter counts from boot). A counter that went down
/// means the sink restarted: counted from 0 again. A status period without a new report warns
/// too (the sink writes a status line every 10 s).
pub fn status_warnings(before: Option<&SinkLine>, now: &SinkLine) -> Vec<String> {
    let Some(n) = now.status_fields() else {
        return Vec::new();
    };
    let b = before
        .and_then(SinkLine::status_fields)
        .unwrap_or([0; STATUS_FIELDS]);
    let restarted = n.iter().zip(&b).any(|(n, b)| n < b);
    let delta = |k: usize| if restarted { n[k] } else { n[k] - b[k] };
    // The counters that warn when they grow (indices of `SinkLine::status_fields`), most
    // telling first, each with what to check.
    const WARN: [(usize, &str); 5] = [
        (
            REPEATS,
            "reports repeated a sequence number their agent had sent: two agents with one id \
             (give each its own: HOPLOC_ID, hoploc provision --id), or a replay",
        ),
        (
            FAILED,
            "reports the agents' radios could not deliver: the sink channel is busy (another \
             network or device on it: pick another HOPLOC_SINK_CHANNEL), or the sink's radio did \
             not acknowledge (sink off, out of range, another PAN or key)",
        ),
        (
            FOREIGN,
            "frames on the sink channel were no hoploc report: another device on the PAN, or a \
             sender with another network key (a PAN id or a key of your own keeps them out)",
        ),
        (CORRUPT, "damaged hoploc messages (failed CRC or values)"),
        (DROPS, "reports missing"),
    ];
    let mut w: Vec<String> = WARN
        .iter()
        .filter(|&&(k, _)| delta(k) > 0)
        .map(|&(k, what)| format!("warning: {} {what}", delta(k)))
        .collect();
    if before.is_some() && !restarted && delta(REPORTS) == 0 && delta(UPTIME) > 0 {
        w.push(format!(
            "warning: no report in the last {} s: are the anchors and an agent on, on the same \
             channels, PAN and key as the sink? (two agents with one id can silence each other)",
            delta(UPTIME)
        ));
    }
    w
}

/// [`SinkLine::status_fields`]' indices.
const UPTIME: usize = 0;
const REPORTS: usize = 2;
const DROPS: usize = 3;
const CORRUPT: usize = 4;
const FOREIGN: usize = 5;
const REPEATS: usize = 7;
const FAILED: usize = 8;

#[cfg(test)]
mod tests {
    use super::*;

    /// A status line of (uptime, frames, reports, drops, corrupt, foreign, repeats, failed).
    fn status(counts: [u32; 8]) -> SinkLine {
        let [uptime_s, frames, reports, drops, checksum_errors, foreign, repeats, failed] = counts;
        SinkLine::Status {
            uptime_s,
            frames,
            reports,
            drops,
            checksum_errors,
            foreign,
            fixes: reports,
            repeats,
            failed,
        }
    }

    #[test]
    fn a_healthy_sink_says_nothing() {
        let a = status([10, 50, 50, 0, 0, 0, 0, 0]);
        let b = status([20, 100, 100, 0, 0, 0, 0, 0]);
        assert!(status_warnings(None, &a).is_empty());
        assert!(status_warnings(Some(&a), &b).is_empty());
        // Not a status line: nothing.
        let fix = SinkLine::NoFix {
            agent: 1,
            seq: 2,
            usable: 2,
        };
        assert!(status_warnings(Some(&a), &fix).is_empty());
    }

    #[test]
    fn each_counter_that_moved_warns_with_what_to_check() {
        let a = status([10, 50, 50, 1, 1, 1, 1, 1]);
        let b = status([20, 90, 70, 3, 2, 11, 9, 4]);
        let w = status_warnings(Some(&a), &b);
        assert_eq!(w.len(), 5, "{w:?}");
        assert!(w[0].contains("8 reports repeated") && w[0].contains("two agents with one id"));
        assert!(w[1].contains("3 reports the agents' radios") && w[1].contains("busy"));
        assert!(w[2].contains("10 frames") && w[2].contains("another device"));
        assert!(w[3].contains("1 damaged"));
        assert!(w[4].contains("2 reports missing"));
    }

    #[test]
    fn a_status_period_without_a_report_warns() {
        let a = status([10, 50, 50, 0, 0, 0, 0, 0]);
        assert!(status_warnings(None, &a).is_empty());
        let b = status([20, 50, 50, 0, 0, 0, 0, 0]);
        let w = status_warnings(Some(&a), &b);
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("no report in the last 10 s"), "{w:?}");
    }

    #[test]
    fn a_restarted_sink_counts_from_boot() {
        let a = status([100, 500, 500, 0, 0, 0, 3, 0]);
        let b = status([10, 10, 10, 0, 0, 0, 2, 0]);
        let w = status_warnings(Some(&a), &b);
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("2 reports repeated"), "{w:?}");
    }
}
