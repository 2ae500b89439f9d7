//! The wire form of a [`Message`]: what a round's datagram carries as its body (symmetric matrices as their upper
//! triangle), and the checks a received body passes before a scheme sees it.

use nalgebra::{DMatrix, DVector};

use super::{Info, Message};
use crate::estimate::Gaussian;
use crate::model::Measurement;
use crate::wire::Body;

fn upper(M: &DMatrix<f64>) -> Vec<f64> {
    let n = M.nrows();
    let mut v = Vec::with_capacity(n * (n + 1) / 2);
    for r in 0..n {
        for c in r..n {
            // The mean of both triangles: what a symmetric matrix off by rounding most likely was.
            v.push(0.5 * (M[(r, c)] + M[(c, r)]));
        }
    }
    v
}

fn symmetric(n: usize, v: &[f64]) -> DMatrix<f64> {
    let mut M = DMatrix::zeros(n, n);
    let mut it = v.iter();
    for r in 0..n {
        for c in r..n {
            let x = *it.next().unwrap_or(&0.0);
            M[(r, c)] = x;
            M[(c, r)] = x;
        }
    }
    M
}

/// Why a round's message cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MessageError {
    #[error("a message of {got} states, the model has {want}")]
    /// A message with another state dimension.
    States {
        /// The message's.
        got: usize,
        /// The model's.
        want: usize,
    },
    /// A measurement row past the model's rows.
    #[error("a measurement with rows beyond the model's {0}")]
    Rows(usize),
    /// A state too large for a datagram.
    #[error("a state of {0} rows cannot travel (at most {max})", max = crate::wire::MAX_STATES)]
    TooLarge(usize),
}

/// The wire form of `m`.
pub fn to_body(m: &Message) -> Result<Body, MessageError> {
    let n_of = |n: usize| u8::try_from(n).ok().filter(|n| *n as usize <= crate::wire::MAX_STATES);
    Ok(match m {
        Message::Measurement(m) => {
            let rows = (0..m.z.len().min(64))
                .filter(|&r| m.present[r])
                .fold(0u64, |acc, r| acc | 1 << r);
            Body::Measurement {
                rows,
                values: (0..m.z.len().min(64))
                    .filter(|&r| m.present[r])
                    .map(|r| m.z[r])
                    .collect(),
            }
        }
        Message::Information(i) => Body::Information {
            n: n_of(i.y.len()).ok_or(MessageError::TooLarge(i.y.len()))?,
            sym: upper(&i.Y),
            vec: i.y.iter().copied().collect(),
        },
        Message::Hybrid { prior, measurement } => Body::Hybrid {
            n: n_of(prior.y.len()).ok_or(MessageError::TooLarge(prior.y.len()))?,
            prior: (upper(&prior.Y), prior.y.iter().copied().collect()),
            measurement: (upper(&measurement.Y), measurement.y.iter().copied().collect()),
        },
        Message::Estimate(g) => Body::Estimate {
            n: n_of(g.x.len()).ok_or(MessageError::TooLarge(g.x.len()))?,
            x: g.x.iter().copied().collect(),
            sym: upper(&g.P),
        },
        Message::Own(bytes) => Body::Own(bytes.to_vec()),
    })
}

/// The message a checked [`Body`] carries, for a model of `states` states and `rows` measurement rows.
pub fn from_body(b: &Body, states: usize, rows: usize) -> Result<Message, MessageError> {
    let dim = |n: u8| {
        if n as usize == states {
            Ok(states)
        } else {
            Err(MessageError::States {
                got: n as usize,
                want: states,
            })
        }
    };
    let info = |n: usize, Y: &[f64], y: &[f64]| Info {
        Y: symmetric(n, Y),
        y: DVector::from_column_slice(y),
    };
    Ok(match b {
        Body::Measurement { rows: mask, values } => {
            if rows < 64 && mask >> rows != 0 {
                return Err(MessageError::Rows(rows));
            }
            let mut m = Measurement::empty(rows);
            m.merge(*mask, values);
            Message::Measurement(m)
        }
        Body::Information { n, sym, vec } => {
            let n = dim(*n)?;
            Message::Information(info(n, sym, vec))
        }
        Body::Hybrid { n, prior, measurement } => {
            let n = dim(*n)?;
            Message::Hybrid {
                prior: info(n, &prior.0, &prior.1),
                measurement: info(n, &measurement.0, &measurement.1),
            }
        }
        Body::Estimate { n, x, sym } => {
            let n = dim(*n)?;
            Message::Estimate(Gaussian {
                x: DVector::from_column_slice(x),
                P: symmetric(n, sym),
            })
        }
        Body::Own(bytes) => Message::Own(bytes::Bytes::copy_from_slice(bytes)),
    })
}
