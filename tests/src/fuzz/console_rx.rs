//! The console's receive path, `dca_app::console::Receiver`: what the
//! board's receive interrupt and its console task do with the bytes and the
//! line queue, in any interleaving.
//!
//! Input: the first byte chooses the queue (the board's 2 KiB, or 160 bytes
//! so that it overflows often); then a program of operations, one byte each
//! (and a payload byte where needed):
//! * receive the next byte (printable, a line end, backspace, or any byte),
//!   or a run of printable bytes;
//! * the receiver lost bytes (`lost`);
//! * the console task takes up to n lines (`next`), draining the echo first;
//! * echo on or off.
//!
//! Invariants:
//! * every line end that completes a non-empty line, or a line the editor
//!   refuses, gets exactly one [`Received`] item, in order: the line editor's
//!   own verdict, or [`LineError::Discarded`] when it did not fit;
//! * delivered lines are printable ASCII of at most [`MAX_LINE`] characters;
//! * echo holds only printable characters, backspace, CR and LF, and only
//!   while echo is on;
//! * with every line taken, the queue is empty.

use dca_app::console::{Edit, LineEditor, LineError, Received, Receiver, MAX_LINE, RX_QUEUE_BYTES};

use super::Bytes;

/// A small queue, so that the discard path is exercised.
const SMALL: usize = 160;

/// What the reference editor says of the line ends in the input, in order.
#[derive(Debug, PartialEq)]
enum Want {
    Line(String),
    Bad(LineError),
}

/// The operations of a program.
enum Op {
    Byte(u8),
    Lost,
    Take(u8),
    Echo(bool),
}

fn program(b: &mut Bytes<'_>) -> Vec<Op> {
    let mut ops = Vec::new();
    while !b.is_empty() {
        let op = b.u8();
        match op % 16 {
            0..=6 => ops.push(Op::Byte(b' ' + b.u8() % 95)),
            7 => ops.push(Op::Byte(if b.u8().is_multiple_of(2) {
                b'\r'
            } else {
                b'\n'
            })),
            8 => ops.push(Op::Byte(0x7f)),
            9 => ops.push(Op::Byte(b.u8())),
            10 => {
                // A paste: a run of printable bytes, then a line end.
                let n = usize::from(b.u8());
                let c = b' ' + b.u8() % 95;
                ops.extend((0..n).map(|_| Op::Byte(c)));
                ops.push(Op::Byte(b'\n'));
            }
            11 => ops.push(Op::Lost),
            12..=14 => ops.push(Op::Take(b.u8() % 8)),
            _ => ops.push(Op::Echo(b.u8().is_multiple_of(2))),
        }
    }
    ops
}

/// Run the program on a receiver of `N` bytes.
fn run<const N: usize>(ops: &[Op]) {
    let mut rx: Receiver<N> = Receiver::new();
    let mut reference = LineEditor::new();
    let mut want: Vec<Want> = Vec::new();
    let mut got: Vec<Result<String, LineError>> = Vec::new();
    let mut echo_on = false;
    let mut buf = [0u8; MAX_LINE];
    let mut take = |rx: &mut Receiver<N>, got: &mut Vec<Result<String, LineError>>, n: usize| {
        while let Some(e) = rx.next_echo() {
            assert!(
                matches!(e, 0x20..=0x7e | 0x08 | b'\r' | b'\n'),
                "echo byte {e:#04x}"
            );
        }
        for _ in 0..n {
            match rx.next(&mut buf) {
                Some(Received::Line(l)) => {
                    assert!(l.len() <= MAX_LINE && l.bytes().all(|c| (0x20..0x7f).contains(&c)));
                    got.push(Ok(l.to_string()));
                }
                Some(Received::Bad(e)) => got.push(Err(e)),
                None => break,
            }
        }
    };
    for op in ops {
        match *op {
            Op::Byte(c) => {
                rx.receive(c);
                match reference.push(c) {
                    Edit::Line(l) => want.push(Want::Line(l.to_string())),
                    Edit::Bad(e) => want.push(Want::Bad(e)),
                    _ => {}
                }
                if !echo_on {
                    assert_eq!(rx.next_echo(), None, "echo while echo is off");
                }
            }
            Op::Lost => {
                rx.lost();
                reference.overrun();
            }
            Op::Take(n) => take(&mut rx, &mut got, usize::from(n)),
            Op::Echo(on) => {
                rx.set_echo(on);
                echo_on = on;
            }
        }
    }
    take(&mut rx, &mut got, usize::MAX);
    assert_eq!(rx.queued_bytes(), 0, "lines left in the queue");
    assert_eq!(got.len(), want.len(), "one reply per line end");
    // Replies are compared position by position: a line answered out of
    // order meets another line's verdict and fails.
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        match (g, w) {
            (Err(LineError::Discarded), _) => {}
            (Ok(a), Want::Line(b)) => assert_eq!(a, b, "line {i}"),
            (Err(a), Want::Bad(b)) => assert_eq!(a, b, "line {i}"),
            _ => panic!("line {i}: got {g:?}, the editor says {w:?}"),
        }
    }
}

/// The harness (see the module documentation).
pub fn console_rx(data: &[u8]) {
    let mut b = Bytes::new(data);
    let small = b.u8() % 2 == 1;
    let ops = program(&mut b);
    if small {
        run::<SMALL>(&ops);
    } else {
        run::<RX_QUEUE_BYTES>(&ops);
    }
}
