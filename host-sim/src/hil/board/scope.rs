//! `host-sim console ... --scope`: a live view of what the board streams, in
//! the terminal (ratatui; works over SSH), with the console beside it.
//!
//! The screen: four charts of the last [`WINDOW_S`] seconds of the telemetry
//! stream (position: reference, Xo and Xi in mm; the line pressures in MPa;
//! the load force in N; the drive command in mm/s), the last replies of the
//! board, and the input line. Typed lines go to the board one at a time as in
//! the interactive console; Enter sends, Backspace erases, Up and Down walk the
//! history, Ctrl-D or Esc ends the session. The view turns the stream on at
//! start (`telemetry on 10`, a row every 10 ms) and off at the end; any
//! `telemetry` command typed changes it.
//!
//! [`ScopeData`] keeps the stream (fed line by line from the console's reader
//! thread) and [`draw`] renders a frame from it, so the view is tested by
//! rendering into ratatui's `TestBackend`.

use std::collections::VecDeque;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::{Axis, Block, Chart, Dataset, GraphType, Paragraph};
use ratatui::Frame;

use super::capture::Capture;
use super::console::{ConsoleClient, LineKind, Reply};
use super::BoardError;

/// Seconds of the stream the charts show.
pub const WINDOW_S: f64 = 10.0;

/// Lines of replies kept on screen.
const REPLY_LINES: usize = 200;

/// The stream's columns a chart shows, in the order of [`ScopeData::series`].
pub const COLUMNS: [&str; 7] = [
    "ref_m", "xo_m", "xi_m", "p1_pa", "p2_pa", "ft_n", "vcmd_mps",
];

/// The last [`WINDOW_S`] seconds of a telemetry stream.
#[derive(Clone, Debug, Default)]
pub struct ScopeData {
    /// Column of each of [`COLUMNS`] in the current stream's rows.
    index: Option<[usize; 7]>,
    /// Time of each row, s.
    t_s: VecDeque<f64>,
    /// The values of [`COLUMNS`], in display units (mm, MPa, N, mm/s).
    values: [VecDeque<f64>; 7],
    /// Rows received since the stream started.
    rows: u64,
}

/// Display unit of a column: the factor from SI.
fn scale(col: usize) -> f64 {
    match col {
        0..=2 => 1e3,  // m -> mm
        3 | 4 => 1e-6, // Pa -> MPa
        5 => 1.0,      // N
        _ => 1e3,      // m/s -> mm/s
    }
}

impl ScopeData {
    /// Nothing received.
    pub fn new() -> Self {
        Self::default()
    }

    /// Feed one line of the stream (`#` metadata, the header, a row).
    pub fn line(&mut self, line: &str) {
        if line == "# dca-log v1" {
            *self = Self::default();
            return;
        }
        if line.starts_with('#') {
            return;
        }
        if let Some(header) = line.strip_prefix("t_s,") {
            let names: Vec<&str> = header.split(',').collect();
            let mut idx = [0usize; 7];
            for (slot, want) in idx.iter_mut().zip(COLUMNS) {
                match names.iter().position(|n| *n == want) {
                    Some(i) => *slot = i + 1,
                    None => return,
                }
            }
            self.index = Some(idx);
            return;
        }
        let Some(idx) = self.index else { return };
        let fields: Vec<&str> = line.split(',').collect();
        let num = |i: usize| fields.get(i).and_then(|f| f.parse::<f64>().ok());
        let Some(t) = num(0) else { return };
        let mut row = [0.0; 7];
        for (k, (v, i)) in row.iter_mut().zip(idx).enumerate() {
            match num(i) {
                Some(x) => *v = x * scale(k),
                None => return,
            }
        }
        self.t_s.push_back(t);
        for (q, v) in self.values.iter_mut().zip(row) {
            q.push_back(v);
        }
        self.rows += 1;
        while self.t_s.front().is_some_and(|t0| t - *t0 > WINDOW_S) {
            self.t_s.pop_front();
            for q in &mut self.values {
                q.pop_front();
            }
        }
    }

    /// Rows received since the stream started.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// The points `(t, value)` of column `col` of [`COLUMNS`] in view.
    pub fn series(&self, col: usize) -> Vec<(f64, f64)> {
        self.t_s
            .iter()
            .copied()
            .zip(self.values[col].iter().copied())
            .collect()
    }

    /// The latest value of column `col`, in display units.
    pub fn last(&self, col: usize) -> Option<f64> {
        self.values[col].back().copied()
    }

    /// The time span in view, s.
    fn x_bounds(&self) -> [f64; 2] {
        match (self.t_s.front(), self.t_s.back()) {
            (Some(_), Some(b)) => [(b - WINDOW_S).max(0.0), b.max(WINDOW_S)],
            _ => [0.0, WINDOW_S],
        }
    }

    /// The value span of columns `cols`, padded; at least `min_span` wide.
    fn y_bounds(&self, cols: &[usize], min_span: f64) -> [f64; 2] {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for &c in cols {
            for &v in &self.values[c] {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        if !lo.is_finite() || !hi.is_finite() {
            return [0.0, min_span];
        }
        let mid = 0.5 * (lo + hi);
        let half = (0.5 * (hi - lo)).max(0.5 * min_span) * 1.1;
        [mid - half, mid + half]
    }
}

/// What the screen shows besides the stream.
#[derive(Clone, Debug, Default)]
pub struct Console {
    /// The line being typed.
    pub input: String,
    /// Replies and notices, oldest first.
    pub lines: VecDeque<String>,
    /// A command is on its way (its reply not in yet).
    pub busy: bool,
}

impl Console {
    /// Add lines to the reply pane.
    pub fn show(&mut self, text: &str) {
        for l in text.lines() {
            self.lines.push_back(l.to_string());
        }
        while self.lines.len() > REPLY_LINES {
            self.lines.pop_front();
        }
    }
}

const COLORS: [Color; 3] = [Color::Yellow, Color::Cyan, Color::Magenta];

/// One chart: its title, its columns (index into [`COLUMNS`], legend name),
/// the smallest value span it shows, its place.
type ChartSpec = (&'static str, Vec<(usize, &'static str)>, f64, Rect);

fn chart<'a>(
    data: &ScopeData,
    title: &'a str,
    cols: &[(usize, &'a str)],
    min_span: f64,
    points: &'a [Vec<(f64, f64)>],
) -> Chart<'a> {
    let x = data.x_bounds();
    let ids: Vec<usize> = cols.iter().map(|(c, _)| *c).collect();
    let y = data.y_bounds(&ids, min_span);
    let datasets: Vec<Dataset<'a>> = cols
        .iter()
        .zip(points)
        .enumerate()
        .map(|(i, ((c, name), pts))| {
            let label = match data.last(*c) {
                Some(v) => format!("{name} {v:.3}"),
                None => (*name).to_string(),
            };
            Dataset::default()
                .name(label)
                .marker(Marker::Braille)
                .graph_type(GraphType::Line)
                .style(Style::default().fg(COLORS[i % COLORS.len()]))
                .data(pts)
        })
        .collect();
    let lab = |v: f64| Span::raw(format!("{v:.1}"));
    let labx = |v: f64| Span::raw(format!("{v:.1} s"));
    Chart::new(datasets)
        .block(Block::bordered().title(title))
        .x_axis(Axis::default().bounds(x).labels([labx(x[0]), labx(x[1])]))
        .y_axis(
            Axis::default()
                .bounds(y)
                .labels([lab(y[0]), lab(0.5 * (y[0] + y[1])), lab(y[1])]),
        )
        .legend_position(Some(ratatui::widgets::LegendPosition::TopLeft))
        .hidden_legend_constraints((Constraint::Percentage(90), Constraint::Percentage(90)))
}

/// Render one frame: the four charts, the replies and the input line.
pub fn draw(f: &mut Frame, data: &ScopeData, console: &Console) {
    let [charts, replies, input] = Layout::vertical([
        Constraint::Min(12),
        Constraint::Length(7),
        Constraint::Length(3),
    ])
    .areas(f.area());
    let [top, bottom] =
        Layout::vertical([Constraint::Percentage(50), Constraint::Percentage(50)]).areas(charts);
    let [a, b] =
        Layout::horizontal([Constraint::Percentage(50), Constraint::Percentage(50)]).areas(top);
    let [c, d] =
        Layout::horizontal([Constraint::Percentage(50), Constraint::Percentage(50)]).areas(bottom);
    let groups: [ChartSpec; 4] = [
        (
            "position, mm",
            vec![(0, "ref"), (1, "xo"), (2, "xi")],
            1.0,
            a,
        ),
        ("pressure, MPa", vec![(3, "p1"), (4, "p2")], 0.1, b),
        ("force, N", vec![(5, "ft")], 10.0, c),
        ("command, mm/s", vec![(6, "vcmd")], 1.0, d),
    ];
    for (title, cols, span, area) in &groups {
        let points: Vec<Vec<(f64, f64)>> = cols.iter().map(|(c, _)| data.series(*c)).collect();
        f.render_widget(chart(data, title, cols, *span, &points), *area);
    }
    let shown = usize::from(replies.height.saturating_sub(2));
    let tail: Vec<Line> = console
        .lines
        .iter()
        .skip(console.lines.len().saturating_sub(shown))
        .map(|l| Line::raw(l.as_str()))
        .collect();
    let title = format!("board ({} rows streamed; Ctrl-D or Esc ends)", data.rows());
    f.render_widget(
        Paragraph::new(tail).block(Block::bordered().title(title)),
        replies,
    );
    let prompt = if console.busy { "... " } else { "dca> " };
    f.render_widget(
        Paragraph::new(format!("{prompt}{}", console.input)).block(Block::bordered()),
        input,
    );
    let x = input.x + 1 + (prompt.len() + console.input.len()) as u16;
    f.set_cursor_position((x.min(input.right().saturating_sub(2)), input.y + 1));
}

/// What a key press asks of the live view.
enum KeyAction {
    /// End the view (Ctrl-D, Esc).
    Quit,
    /// Send this line to the board (Enter on a non-empty line while no reply is due).
    Send(String),
    /// The input line or the history position changed, or nothing did.
    Edit,
}

/// Apply a key press to the input line and the history (`back`: how far up
/// the history the input line is, 0 for a new line).
fn on_key(
    console: &mut Console,
    history: &mut Vec<String>,
    back: &mut usize,
    k: ratatui::crossterm::event::KeyEvent,
) -> KeyAction {
    use ratatui::crossterm::event::{KeyCode, KeyModifiers};
    let ctrl = k.modifiers.contains(KeyModifiers::CONTROL);
    match k.code {
        KeyCode::Esc => return KeyAction::Quit,
        KeyCode::Char('d') if ctrl => return KeyAction::Quit,
        KeyCode::Char('c') if ctrl => console.input.clear(),
        KeyCode::Char(c) if !ctrl && console.input.len() < 80 => {
            console.input.push(c);
        }
        KeyCode::Backspace => {
            console.input.pop();
        }
        KeyCode::Up if *back < history.len() => {
            *back += 1;
            console.input = history[history.len() - *back].clone();
        }
        KeyCode::Down if *back > 0 => {
            *back -= 1;
            console.input = if *back == 0 {
                String::new()
            } else {
                history[history.len() - *back].clone()
            };
        }
        KeyCode::Enter => {
            let line = console.input.trim().to_string();
            console.input.clear();
            *back = 0;
            if !line.is_empty() && !console.busy {
                history.push(line.clone());
                console.busy = true;
                return KeyAction::Send(line);
            }
        }
        _ => {}
    }
    KeyAction::Edit
}

/// Run the live view on `client` until Ctrl-D or Esc; the stream goes to
/// the charts (and to `capture`, if given). Every reply is also given to
/// `on_reply` with its line (the session's count); a note it returns is
/// shown with the reply.
pub fn run_scope(
    client: &mut ConsoleClient,
    capture: Option<Arc<Mutex<Capture>>>,
    mut on_reply: impl FnMut(&str, &Reply) -> Option<String>,
) -> Result<(), BoardError> {
    use ratatui::crossterm::event::{self, Event, KeyEventKind};
    let data = Arc::new(Mutex::new(ScopeData::new()));
    let notices: Arc<Mutex<Vec<String>>> = Arc::default();
    {
        let (data, notices) = (Arc::clone(&data), Arc::clone(&notices));
        client.set_sink(Some(Box::new(move |kind, line| {
            if kind == LineKind::Stream {
                if let Some(c) = &capture {
                    if let Ok(mut c) = c.lock() {
                        c.line(line);
                    }
                }
                if let Ok(mut d) = data.lock() {
                    d.line(line);
                }
            } else if let Ok(mut n) = notices.lock() {
                n.push(line.to_string());
            }
        })));
    }
    let io_err = |e: std::io::Error| BoardError::Io {
        port: "terminal".into(),
        error: e,
    };
    let mut console = Console::default();
    let mut history: Vec<String> = Vec::new();
    let mut back = 0usize;
    let (to_board, lines) = mpsc::channel::<String>();
    let (replies_tx, replies) = mpsc::channel::<(String, Result<Reply, BoardError>)>();
    std::thread::scope(|s| -> Result<(), BoardError> {
        // The board's side: one command at a time, as the console answers.
        s.spawn(move || {
            for line in lines {
                let r = client.command(&line);
                if replies_tx.send((line, r)).is_err() {
                    break;
                }
            }
        });
        let _ = to_board.send("telemetry on 10".into());
        console.busy = true;
        let mut terminal = ratatui::try_init().map_err(io_err)?;
        let result = (|| -> Result<(), BoardError> {
            loop {
                while let Ok((line, r)) = replies.try_recv() {
                    console.busy = false;
                    match r {
                        Ok(reply) => {
                            console.show(&format!("> {line}"));
                            console.show(&reply.text());
                            if let Some(note) = on_reply(&line, &reply) {
                                console.show(&note);
                            }
                        }
                        Err(e @ BoardError::NoReply { .. }) => {
                            console.show(&e.to_string());
                            let timed_out = Reply {
                                last: format!("error: {e}"),
                                ..Reply::default()
                            };
                            on_reply(&line, &timed_out);
                        }
                        Err(e) => return Err(e),
                    }
                }
                if let Ok(mut n) = notices.lock() {
                    for l in n.drain(..) {
                        console.show(&l);
                    }
                }
                {
                    let d = data.lock().map(|d| d.clone()).unwrap_or_default();
                    terminal.draw(|f| draw(f, &d, &console)).map_err(io_err)?;
                }
                if !event::poll(Duration::from_millis(50)).map_err(io_err)? {
                    continue;
                }
                let Event::Key(k) = event::read().map_err(io_err)? else {
                    continue;
                };
                if k.kind != KeyEventKind::Press {
                    continue;
                }
                match on_key(&mut console, &mut history, &mut back, k) {
                    KeyAction::Quit => return Ok(()),
                    KeyAction::Send(line) => {
                        let _ = to_board.send(line);
                    }
                    KeyAction::Edit => {}
                }
            }
        })();
        ratatui::restore();
        // Stream off, then the board's thread ends with the channel.
        let _ = to_board.send("telemetry off".into());
        drop(to_board);
        result
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratatui::backend::TestBackend;
    use ratatui::Terminal;

    #[test]
    fn keys_edit_the_line_send_it_once_and_walk_the_history() {
        use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
        let key = |c| KeyEvent::new(c, KeyModifiers::NONE);
        let (mut console, mut history, mut back) = (Console::default(), Vec::new(), 0);
        let mut press = |c: &mut Console, h: &mut Vec<String>, k| on_key(c, h, &mut back, k);
        for ch in "arm".chars() {
            assert!(matches!(
                press(&mut console, &mut history, key(KeyCode::Char(ch))),
                KeyAction::Edit
            ));
        }
        match press(&mut console, &mut history, key(KeyCode::Enter)) {
            KeyAction::Send(l) => assert_eq!(l, "arm"),
            _ => panic!("Enter sends the line"),
        }
        assert!(console.busy && console.input.is_empty());
        // While a reply is due, Enter sends nothing.
        press(&mut console, &mut history, key(KeyCode::Char('x')));
        assert!(matches!(
            press(&mut console, &mut history, key(KeyCode::Enter)),
            KeyAction::Edit
        ));
        console.busy = false;
        press(&mut console, &mut history, key(KeyCode::Up));
        assert_eq!(console.input, "arm");
        press(&mut console, &mut history, key(KeyCode::Down));
        assert_eq!(console.input, "");
        let ctrl_d = KeyEvent::new(KeyCode::Char('d'), KeyModifiers::CONTROL);
        assert!(matches!(
            press(&mut console, &mut history, ctrl_d),
            KeyAction::Quit
        ));
        assert!(matches!(
            press(&mut console, &mut history, key(KeyCode::Esc)),
            KeyAction::Quit
        ));
    }

    fn stream(d: &mut ScopeData, rows: usize) {
        d.line("# dca-log v1");
        d.line("# controller=mpc-eso");
        d.line("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n,state,faults");
        for k in 0..rows {
            let t = k as f64 * 0.01;
            let x = 0.02 * (1.0 - (-t).exp());
            d.line(&format!(
                "{t:.3},0.0200000,{:.7},{x:.8},{:.8},{:.1},1000000.0,{:.2},2,0",
                0.02 * (-t).exp(),
                x * 0.99,
                2.0e6 + 1.0e5 * t,
                -50.0 * t
            ));
        }
    }

    fn screen(term: &Terminal<TestBackend>) -> Vec<String> {
        let b = term.backend().buffer();
        (0..b.area.height)
            .map(|y| {
                (0..b.area.width)
                    .map(|x| b[(x, y)].symbol().to_string())
                    .collect()
            })
            .collect()
    }

    #[test]
    fn the_stream_keeps_its_last_window_in_display_units() {
        let mut d = ScopeData::new();
        stream(&mut d, 1500); // 15 s at 10 ms
        assert_eq!(d.rows(), 1500);
        let pos = d.series(1);
        assert!((pos[0].0 - 4.99).abs() < 1e-9, "{:?}", pos[0]);
        assert!((pos.last().unwrap().0 - 14.99).abs() < 1e-9);
        assert!((d.last(0).unwrap() - 20.0).abs() < 1e-9, "ref in mm");
        assert!((d.last(4).unwrap() - 1.0).abs() < 1e-9, "p2 in MPa");
        // A new stream starts the view again; rows before a header are not read.
        d.line("# dca-log v1");
        d.line("0.000,1,2,3,4,5,6,7,8,9");
        assert_eq!(d.rows(), 0);
        assert!(d.series(0).is_empty());
    }

    #[test]
    fn the_view_shows_four_charts_the_replies_and_the_input_line() {
        let mut d = ScopeData::new();
        stream(&mut d, 600);
        let mut c = Console::default();
        c.show("> goto 20\nok");
        c.input = "sine 5 0.5".into();
        let mut term = Terminal::new(TestBackend::new(120, 40)).unwrap();
        term.draw(|f| draw(f, &d, &c)).unwrap();
        let rows = screen(&term);
        let text = rows.join("\n");
        for want in [
            "position, mm",
            "pressure, MPa",
            "force, N",
            "command, mm/s",
            "ref 20.000",
            "p1 2.599",
            "ft -299.500",
            "> goto 20",
            "dca> sine 5 0.5",
            "600 rows streamed",
        ] {
            assert!(text.contains(want), "{want:?} not on screen:\n{text}");
        }
        // The traces are drawn (braille dots) in each chart's quarter.
        let braille = |r: std::ops::Range<usize>, cols: std::ops::Range<usize>| {
            rows[r].iter().any(|l| {
                l.chars()
                    .skip(cols.start)
                    .take(cols.len())
                    .any(|ch| ('\u{2801}'..='\u{28ff}').contains(&ch))
            })
        };
        assert!(braille(1..15, 0..60), "position trace\n{text}");
        assert!(braille(1..15, 60..120), "pressure trace\n{text}");
        assert!(braille(16..30, 0..60), "force trace\n{text}");
        assert!(braille(16..30, 60..120), "command trace\n{text}");
    }

    #[test]
    fn an_empty_stream_draws_empty_charts() {
        let d = ScopeData::new();
        let c = Console::default();
        let mut term = Terminal::new(TestBackend::new(80, 30)).unwrap();
        term.draw(|f| draw(f, &d, &c)).unwrap();
        let text = screen(&term).join("\n");
        assert!(
            text.contains("position, mm") && text.contains("dca> "),
            "{text}"
        );
        assert!(!text
            .chars()
            .any(|ch| ('\u{2801}'..='\u{28ff}').contains(&ch)));
    }
}
