//! The three node roles.

/// A node's role; each is one firmware (`anchor-fw`, `agent-fw`, `sink-fw`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Role {
    /// Known position; broadcasts beacons in its TDMA slot.
    Anchor,
    /// The node being located; collects beacons and reports them to the sink.
    Agent,
    /// Receives reports and estimates the agents' positions.
    Sink,
}

impl Role {
    /// Every role, in network order.
    pub const ALL: [Role; 3] = [Role::Anchor, Role::Agent, Role::Sink];

    /// The role's name in lines and on the command line: `anchor`, `agent`, `sink`.
    pub const fn name(self) -> &'static str {
        match self {
            Role::Anchor => "anchor",
            Role::Agent => "agent",
            Role::Sink => "sink",
        }
    }

    /// The role of a name (exact, lower case).
    pub fn from_name(name: &str) -> Option<Role> {
        Role::ALL.into_iter().find(|r| r.name() == name)
    }

    /// The testbed channel the role's radio starts on: anchors and agents on the first channel
    /// of the default list (where the first beacons go), the sink on the sink channel (where
    /// reports come).
    pub const fn boot_channel(self) -> u8 {
        match self {
            Role::Sink => crate::DEFAULT_SINK_CHANNEL,
            Role::Anchor | Role::Agent => crate::DEFAULT_CHANNELS[0],
        }
    }

    /// The radio's 16-bit address (`MY`) of node `id` of this role: anchors `id`, agents
    /// `0x0100 + id`, sinks `0x0200 + id`, so the three never overlap and none is the broadcast
    /// address 0xFFFF.
    pub const fn address(self, id: u8) -> u16 {
        let base = match self {
            Role::Anchor => 0x0000,
            Role::Agent => 0x0100,
            Role::Sink => 0x0200,
        };
        base | id as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for r in Role::ALL {
            assert_eq!(Role::from_name(r.name()), Some(r));
        }
        assert_eq!(Role::from_name("Anchor"), None);
        assert_eq!(Role::from_name(""), None);
    }

    #[test]
    fn boot_channels() {
        assert_eq!(Role::Anchor.boot_channel(), 1);
        assert_eq!(Role::Agent.boot_channel(), 1);
        assert_eq!(Role::Sink.boot_channel(), 3);
    }

    #[test]
    fn addresses_do_not_overlap() {
        let mut seen = std::collections::HashSet::new();
        for r in Role::ALL {
            for id in 0..=255 {
                let a = r.address(id);
                assert_ne!(a, 0xFFFF);
                assert!(seen.insert(a), "{r:?} {id}");
            }
        }
    }
}
