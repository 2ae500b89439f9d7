//! The medium of a run: every directed link with its rules and its seeded streams, one per sender, or one shared
//! radio channel; and what stands in front of a receiver (the outsiders attacking it).

use super::Scenario;
use crate::link::{Egress, Link};
use crate::medium::radio::RadioMedium;
use crate::medium::{Ingress, Medium, PairwiseMedium};

impl Scenario {
    /// What carries every node's datagrams in one process: the scenario's links, or its radio channel.
    pub fn whole_medium(&self) -> Box<dyn Medium> {
        match self.radio_medium() {
            Some(radio) => Box::new(radio),
            None => Box::new(self.pairwise_medium(0..self.nodes().len())),
        }
    }

    /// The shared channel of `[medium] kind = "radio"` (none for the pairwise medium): every node a radio where
    /// [`Scenario::world`] places it, its broadcasts for its out-neighbours, its backoffs and its frames' fates drawn
    /// from streams of the run's seed. Sealed datagrams travel as secured frames, simnet's sequence number and tag
    /// standing for the frame counter and the MIC.
    pub fn radio_medium(&self) -> Option<RadioMedium> {
        let super::MediumConfig::Radio(mut radio) = *self.medium() else {
            return None;
        };
        if self.security().key.is_some() {
            radio.security = crate::medium::frame::Security::Mic64;
        }
        let listeners = (0..self.nodes().len())
            .map(|i| self.out_links(i).map(|l| l.to).collect())
            .collect();
        Some(RadioMedium::new(radio, self.world(), self.sim().seed).with_listeners(listeners))
    }

    /// The links out of `senders` as a [`PairwiseMedium`]: each directed link with its rules and its stream
    /// (seed, "link", from, to), and one stream per consensus round when the nodes run distributed estimators (round
    /// r meets the same fates whatever L is). A driver that holds some senders builds their part alone.
    pub fn pairwise_medium(&self, senders: impl IntoIterator<Item = usize>) -> PairwiseMedium {
        let seed = self.sim().seed;
        let link_on = |l: &super::DirectedLink, stream: &str| {
            Link::new(
                l.from,
                l.to,
                l.config,
                crate::rng::stream(seed, stream, l.from as u64, l.to as u64),
            )
        };
        let rounds = if self.estimators().any_in_node() {
            self.estimators().rounds
        } else {
            0
        };
        senders.into_iter().fold(PairwiseMedium::new(), |m, i| {
            let links = self.out_links(i).map(|l| link_on(l, "link")).collect();
            let round_links = (0..rounds)
                .map(|r| {
                    self.out_links(i)
                        .map(|l| link_on(l, &format!("link-round-{r}")))
                        .collect()
                })
                .collect();
            m.with_sender(i, Egress::with_rounds(links, round_links))
        })
    }

    /// What stands in front of node `index`: the outsiders of `[[attack]]` aimed at it, on their stream
    /// (seed, "attack", index); none when no attack is.
    pub fn ingress(&self, index: usize) -> Option<Box<dyn Ingress>> {
        let air = crate::attack::Air::new(self.attacks(), index, |j| self.nodes()[j].id, self.sim().seed);
        (!air.is_empty()).then(|| Box::new(air) as Box<dyn Ingress>)
    }
}
