//! The medium of a run's links: every directed link with its rules and its seeded streams, one per sender; and what
//! stands in front of a receiver (the outsiders attacking it).

use super::Scenario;
use crate::link::{Egress, Link};
use crate::medium::{Ingress, PairwiseMedium};

impl Scenario {
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
