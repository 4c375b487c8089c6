//! Hardware setup: the only module that configures peripherals.
//!
//! [`setup`] takes the core and device peripherals from RTIC's `init`, brings up
//! the clock tree, the pins and every peripheral the tasks use, and returns them
//! in one [`Devices`] struct. The tasks never configure hardware themselves;
//! they use the small drivers defined here ([`UsClock`], [`TickTimer`],
//! [`Drive`], [`Watchdog`], [`SettingsStore`] and the sensor front end).
//!
//! # Pin map (STM32F417VE, LQFP100)
//!
//! | signal | pin | peripheral |
//! |---|---|---|
//! | LVDT (Xo) | PC0 | ADC1_IN10 |
//! | pressure P1 | PC1 | ADC1_IN11 |
//! | pressure P2 | PC2 | ADC1_IN12 |
//! | force Ft | PC3 | ADC1_IN13 |
//! | motor encoder A / B (Xi) | PA0 / PA1 | TIM5_CH1 / CH2, encoder mode, 32 bit |
//! | drive speed PWM (20 kHz) | PA8 | TIM1_CH1 |
//! | drive direction | PB12 | GPIO out (high = extend, `drive.invert` swaps) |
//! | drive enable | PB13 | GPIO out (high = enabled) |
//! | console TX / RX (115200 8N1) | PA9 / PA10 | USART1 |
//! | HIL link TX / RX (921600 8N1) | PA2 / PA3 | USART2 |
//!
//! Internal: TIM3 is the 1 kHz control timer (its update event triggers the
//! ADC scan through TRGO), SysTick the 1 kHz housekeeping tick, TIM2 a
//! free-running 1 MHz clock for deadlines, DMA2 stream 0 channel 0 moves the four conversions, the IWDG
//! watches the control task, and flash sector 7 (0x0806_0000, 128 KiB; kept
//! out of the program by `memory.x`) holds the settings.
//!
//! # The `qemu` build
//! QEMU's `netduinoplus2` emulates neither the RCC, nor the ADC, DMA, TIM1,
//! GPIO, IWDG nor the flash interface, and its timer model's periodic update
//! interrupt is unreliable. That build skips the clock setup, runs the control
//! task from the SysTick tick with a simulated sensor source
//! (or HIL frames), drives nothing, and keeps the settings in RAM.

use stm32f4xx_hal::{
    gpio::GpioExt as _,
    pac,
    rcc::{Rcc, RccExt as _},
    serial::{self, Serial},
    time::Bps,
    timer::Timer,
};

#[cfg(not(feature = "qemu"))]
use stm32f4xx_hal::{
    adc::{
        config::{AdcConfig, Dma, ExternalTrigger, SampleTime, Scan, Sequence, TriggerMode},
        Adc,
    },
    dma::{config::DmaConfig, PeripheralToMemory, Stream0, StreamsTuple, Transfer},
    flash::{FlashExt as _, LockedFlash},
    gpio::{Output, Pin},
    qei::Qei,
    rcc::Config,
    time::Hertz,
    timer::{PwmChannel, PwmExt as _},
    watchdog::IndependentWatchdog,
};

use dca_app::settings::IMAGE_LEN;

/// HSE crystal on the board, Hz.
#[cfg(not(feature = "qemu"))]
pub const HSE_HZ: u32 = 8_000_000;

/// Core clock (SYSCLK = HCLK), Hz: 168 MHz from the HSE through the main PLL on
/// the board; QEMU's fixed core clock in the `qemu` build.
pub const SYSCLK_HZ: u32 = 168_000_000;

/// Clock of the APB1 timers (TIM2 ... TIM5), Hz: 2 x PCLK1 = 84 MHz on the
/// board.
#[cfg(not(feature = "qemu"))]
pub const TIMER_CLK_HZ: u32 = 84_000_000;
/// QEMU clocks its STM32 timer model at 1 GHz whatever the RCC says (its
/// counter reads are right; its periodic update interrupt is not, hence the
/// SysTick [`Ticker`]).
#[cfg(feature = "qemu")]
pub const TIMER_CLK_HZ: u32 = 1_000_000_000;

/// Control period, us (1 kHz base tick).
pub const CONTROL_PERIOD_US: u32 = 1_000;

/// Console baud rate.
pub const CONSOLE_BAUD: u32 = 115_200;
/// HIL link baud rate.
pub const HIL_BAUD: u32 = 921_600;

/// Watchdog timeout in normal operation, ms.
pub const WATCHDOG_MS: u32 = 50;
/// Watchdog timeout while the flash is erased and written, ms (the CPU stalls
/// up to 2 s per 128 KiB sector erase, RM0090 / DS8626).
pub const WATCHDOG_FLASH_MS: u32 = 4_000;

/// The console USART.
pub type ConsoleSerial = Serial<pac::USART1>;
/// Console transmitter.
pub type ConsoleTx = serial::Tx<pac::USART1>;
/// Console receiver.
pub type ConsoleRx = serial::Rx<pac::USART1>;
/// HIL transmitter.
pub type HilTx = serial::Tx<pac::USART2>;
/// HIL receiver.
pub type HilRx = serial::Rx<pac::USART2>;

/// Free-running microsecond clock on TIM2 (32 bit, wraps after 71 minutes).
pub struct UsClock {
    tim: pac::TIM2,
}

impl UsClock {
    fn new(tim: pac::TIM2) -> Self {
        tim.cr1().modify(|_, w| w.cen().clear_bit());
        tim.psc()
            .write(|w| w.psc().set((TIMER_CLK_HZ / 1_000_000 - 1) as u16));
        tim.arr().write(|w| w.arr().set(u32::MAX));
        // Load the prescaler now, then start counting from 0.
        tim.egr().write(|w| w.ug().set_bit());
        tim.sr().write(|w| w.uif().clear_bit());
        tim.cr1().modify(|_, w| w.cen().set_bit());
        Self { tim }
    }

    /// Microseconds since start-up, modulo 2^32.
    #[inline]
    pub fn now_us(&self) -> u32 {
        self.tim.cnt().read().bits()
    }
}

/// The 1 kHz control timer on TIM3: its update event is the ADC trigger
/// (TRGO). It raises no interrupt: the housekeeping tick is SysTick's.
pub struct TickTimer {
    tim: pac::TIM3,
}

impl TickTimer {
    fn new(tim: pac::TIM3) -> Self {
        tim.cr1().modify(|_, w| w.cen().clear_bit());
        tim.psc()
            .write(|w| w.psc().set((TIMER_CLK_HZ / 1_000_000 - 1) as u16));
        tim.arr()
            .write(|w| w.arr().set((CONTROL_PERIOD_US - 1) as u16));
        tim.cr2().modify(|_, w| w.mms().update());
        tim.egr().write(|w| w.ug().set_bit());
        tim.sr().write(|w| w.uif().clear_bit());
        Self { tim }
    }

    /// Start counting (after `init`, when the tasks are ready).
    pub fn start(&mut self) {
        self.tim.cr1().modify(|_, w| w.cen().set_bit());
    }

    /// Stop counting: no ADC triggers and no ticks (used around flash writes).
    pub fn pause(&mut self) {
        self.tim.cr1().modify(|_, w| w.cen().clear_bit());
    }
}

/// The 1 kHz housekeeping tick on SysTick (core clock): uptime, watchdog,
/// HIL timeout, and under QEMU the local control release.
pub struct Ticker {
    syst: cortex_m::peripheral::SYST,
}

impl Ticker {
    fn new(mut syst: cortex_m::peripheral::SYST, sysclk_hz: u32) -> Self {
        use cortex_m::peripheral::syst::SystClkSource;
        syst.disable_counter();
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(sysclk_hz / 1_000 - 1);
        syst.clear_current();
        syst.enable_interrupt();
        Self { syst }
    }

    /// Start ticking.
    pub fn start(&mut self) {
        self.syst.enable_counter();
    }
}

/// The independent watchdog (a no-op under QEMU, which does not emulate it).
pub struct Watchdog {
    #[cfg(not(feature = "qemu"))]
    iwdg: IndependentWatchdog,
}

impl Watchdog {
    /// Reload the counter.
    #[inline]
    pub fn feed(&mut self) {
        #[cfg(not(feature = "qemu"))]
        self.iwdg.feed();
    }

    /// Change the timeout (and reload).
    pub fn set_timeout_ms(&mut self, _ms: u32) {
        #[cfg(not(feature = "qemu"))]
        {
            use stm32f4xx_hal::prelude::_fugit_ExtU32 as _;
            self.iwdg.start(_ms.millis());
        }
    }
}

/// Speed command to the servo drive: PWM duty on TIM1_CH1, direction and
/// enable lines. Under QEMU it only remembers the last output.
pub struct Drive {
    #[cfg(not(feature = "qemu"))]
    pwm: PwmChannel<pac::TIM1, 0>,
    #[cfg(not(feature = "qemu"))]
    dir: Pin<'B', 12, Output>,
    #[cfg(not(feature = "qemu"))]
    enable: Pin<'B', 13, Output>,
    last: (f32, bool, bool),
}

impl Drive {
    /// Apply a duty (0 ... 1), a direction (true = extend) and the enable line.
    /// Disabled means duty 0 and the enable line low.
    pub fn set(&mut self, duty: f32, extend: bool, enabled: bool) {
        let duty = if enabled && duty.is_finite() {
            duty.clamp(0.0, 1.0)
        } else {
            0.0
        };
        #[cfg(not(feature = "qemu"))]
        {
            let max = self.pwm.get_max_duty() as f32;
            self.pwm.set_duty((duty * max) as u16);
            self.dir.set_state(extend.into());
            self.enable.set_state(enabled.into());
        }
        self.last = (duty, extend, enabled);
    }

    /// The last output: duty, direction, enabled.
    pub fn last(&self) -> (f32, bool, bool) {
        self.last
    }
}

/// Raw readings of the board's sensors.
#[derive(Clone, Copy, Debug, Default)]
pub struct RawSample {
    /// ADC codes: LVDT, P1, P2, force.
    pub adc: [u16; 4],
    /// Encoder count (two's complement of TIM5's counter).
    pub encoder: i32,
}

/// DMA buffer of one ADC scan.
pub type AdcBuffer = &'static mut [u16; 4];

/// The board's sensor front end: the ADC scan moved by DMA and the encoder.
#[cfg(not(feature = "qemu"))]
pub struct SensorFrontEnd {
    transfer: Transfer<Stream0<pac::DMA2>, 0, Adc<pac::ADC1>, PeripheralToMemory, AdcBuffer>,
    spare: Option<AdcBuffer>,
    encoder: Qei<pac::TIM5>,
    codes: [u16; 4],
}

#[cfg(not(feature = "qemu"))]
impl SensorFrontEnd {
    /// The DMA finished one scan: keep its codes and give the DMA the other
    /// buffer. Returns false if the DMA refused the buffer (the scan is lost).
    pub fn on_transfer_complete(&mut self) -> bool {
        let Some(spare) = self.spare.take() else {
            return false;
        };
        match self.transfer.next_transfer(spare) {
            Ok((done, _)) => {
                self.codes = *done;
                self.spare = Some(done);
                true
            }
            Err(_) => false,
        }
    }

    /// The last scan and the encoder now.
    pub fn read(&self) -> RawSample {
        RawSample {
            adc: self.codes,
            encoder: stm32f4xx_hal::hal_02::Qei::count(&self.encoder) as i32,
        }
    }
}

/// Non-volatile settings: the last flash sector on the board.
pub struct SettingsStore {
    #[cfg(not(feature = "qemu"))]
    flash: LockedFlash,
    #[cfg(feature = "qemu")]
    ram: Option<[u8; IMAGE_LEN]>,
}

/// Flash sector of the settings (STM32F417VE: sector 7, 128 KiB).
#[cfg(not(feature = "qemu"))]
const SETTINGS_SECTOR: u8 = 7;
/// Offset of that sector from the start of the flash.
#[cfg(not(feature = "qemu"))]
const SETTINGS_OFFSET: usize = 0x6_0000;

impl SettingsStore {
    /// Copy the stored image into `buf`; false if there is none (erased flash).
    pub fn read(&self, buf: &mut [u8; IMAGE_LEN]) -> bool {
        #[cfg(not(feature = "qemu"))]
        {
            let mem = self.flash.read();
            let Some(img) = mem.get(SETTINGS_OFFSET..SETTINGS_OFFSET + IMAGE_LEN) else {
                return false;
            };
            if img.iter().all(|b| *b == 0xff) {
                return false;
            }
            buf.copy_from_slice(img);
            true
        }
        #[cfg(feature = "qemu")]
        match &self.ram {
            Some(img) => {
                buf.copy_from_slice(img);
                true
            }
            None => false,
        }
    }

    /// Erase the sector and write `image`, then read it back. The CPU stalls
    /// while the flash is busy: call with the control timer paused and the
    /// watchdog extended.
    pub fn write(&mut self, image: &[u8; IMAGE_LEN]) -> Result<(), &'static str> {
        #[cfg(not(feature = "qemu"))]
        {
            {
                let mut unlocked = self.flash.unlocked();
                unlocked
                    .erase(SETTINGS_SECTOR)
                    .map_err(|_| "flash erase failed")?;
                unlocked
                    .program(SETTINGS_OFFSET, image.iter())
                    .map_err(|_| "flash write failed")?;
            }
            let mut back = [0u8; IMAGE_LEN];
            if !self.read(&mut back) || back != *image {
                return Err("flash verify failed");
            }
            Ok(())
        }
        #[cfg(feature = "qemu")]
        {
            self.ram = Some(*image);
            Ok(())
        }
    }
}

/// The devices of the board, set up and ready for the tasks.
pub struct Devices {
    /// The core clock, Hz.
    pub sysclk_hz: u32,
    /// The housekeeping tick (not yet started).
    pub ticker: Ticker,
    /// Microsecond clock for deadlines.
    pub clock: UsClock,
    /// The 1 kHz control timer (not yet started).
    pub tick: TickTimer,
    /// ADC + DMA + encoder.
    #[cfg(not(feature = "qemu"))]
    pub sensors: SensorFrontEnd,
    /// The servo drive output (disabled).
    pub drive: Drive,
    /// Console USART, RX interrupt enabled.
    pub console: (ConsoleTx, ConsoleRx),
    /// HIL USART, RX interrupt enabled.
    pub hil: (HilTx, HilRx),
    /// The watchdog, running.
    pub watchdog: Watchdog,
    /// Settings storage.
    pub store: SettingsStore,
    /// The last reset was caused by the independent watchdog.
    pub watchdog_reset: bool,
}

fn clocks(rcc: pac::RCC) -> (Rcc, u32) {
    #[cfg(not(feature = "qemu"))]
    {
        let rcc =
            rcc.freeze(Config::hse(Hertz::from_raw(HSE_HZ)).sysclk(Hertz::from_raw(SYSCLK_HZ)));
        let sysclk = rcc.clocks.sysclk().raw();
        (rcc, sysclk)
    }
    // QEMU does not emulate the RCC (`freeze` would wait for HSERDY forever).
    #[cfg(feature = "qemu")]
    (rcc.constrain(), SYSCLK_HZ)
}

/// Sets up the clocks and every peripheral; returns the devices with the
/// control timer stopped and the drive disabled. `adc_buffers` are the two
/// DMA buffers of the ADC scan.
pub fn setup(
    core: cortex_m::Peripherals,
    device: pac::Peripherals,
    _adc_buffers: (AdcBuffer, AdcBuffer),
) -> Devices {
    // Read (and clear) the reset cause before anything else.
    let csr = device.RCC.csr().read();
    let watchdog_reset = csr.wdgrstf().bit_is_set();
    device.RCC.csr().modify(|_, w| w.rmvf().set_bit());

    let (mut rcc, sysclk_hz) = clocks(device.RCC);

    let gpioa = device.GPIOA.split(&mut rcc);
    #[cfg(not(feature = "qemu"))]
    let gpiob = device.GPIOB.split(&mut rcc);
    #[cfg(not(feature = "qemu"))]
    let gpioc = device.GPIOC.split(&mut rcc);

    // Timers: enable their clocks through the HAL, then program them directly.
    let clock = UsClock::new(Timer::new(device.TIM2, &mut rcc).release());
    let tick = TickTimer::new(Timer::new(device.TIM3, &mut rcc).release());

    let console = Serial::new(
        device.USART1,
        (gpioa.pa9, gpioa.pa10),
        serial::Config::default().baudrate(Bps(CONSOLE_BAUD)),
        &mut rcc,
    )
    .unwrap_or_else(|_| defmt::panic!("console USART configuration"));
    let hil = Serial::new(
        device.USART2,
        (gpioa.pa2, gpioa.pa3),
        serial::Config::default().baudrate(Bps(HIL_BAUD)),
        &mut rcc,
    )
    .unwrap_or_else(|_| defmt::panic!("HIL USART configuration"));
    let (console_tx, mut console_rx) = console.split();
    let (hil_tx, mut hil_rx) = hil.split();
    {
        use stm32f4xx_hal::serial::RxListen as _;
        console_rx.listen();
        hil_rx.listen();
    }

    #[cfg(not(feature = "qemu"))]
    let (sensors, drive, watchdog, store) = {
        // ADC1: scan of the four channels, triggered by TIM3 TRGO, by DMA.
        let adc_config = AdcConfig::default()
            .dma(Dma::Continuous)
            .scan(Scan::Enabled)
            .external_trigger(TriggerMode::RisingEdge, ExternalTrigger::Tim_3_trgo);
        let mut adc = Adc::new(device.ADC1, true, adc_config, &mut rcc);
        let st = SampleTime::Cycles_84;
        adc.configure_channel(&gpioc.pc0.into_analog(), Sequence::One, st);
        adc.configure_channel(&gpioc.pc1.into_analog(), Sequence::Two, st);
        adc.configure_channel(&gpioc.pc2.into_analog(), Sequence::Three, st);
        adc.configure_channel(&gpioc.pc3.into_analog(), Sequence::Four, st);
        let dma = StreamsTuple::new(device.DMA2, &mut rcc);
        let dma_config = DmaConfig::default()
            .transfer_complete_interrupt(true)
            .memory_increment(true)
            .double_buffer(false);
        let (first, second) = _adc_buffers;
        let mut transfer = Transfer::init_peripheral_to_memory(dma.0, adc, first, None, dma_config);
        transfer.start(|adc| adc.enable());
        let encoder = Qei::new(device.TIM5, (gpioa.pa0, gpioa.pa1), &mut rcc);
        let sensors = SensorFrontEnd {
            transfer,
            spare: Some(second),
            encoder,
            codes: [0; 4],
        };

        let (_, (ch1, ..)) = device.TIM1.pwm_hz(Hertz::from_raw(20_000), &mut rcc);
        let mut pwm = ch1.with(gpioa.pa8);
        pwm.set_duty(0);
        pwm.enable();
        let mut drive = Drive {
            pwm,
            dir: gpiob.pb12.into_push_pull_output(),
            enable: gpiob.pb13.into_push_pull_output(),
            last: (0.0, true, false),
        };
        drive.set(0.0, true, false);

        let mut iwdg = IndependentWatchdog::new(device.IWDG);
        {
            use stm32f4xx_hal::prelude::_fugit_ExtU32 as _;
            iwdg.start(WATCHDOG_MS.millis());
        }
        let store = SettingsStore {
            flash: LockedFlash::new(device.FLASH),
        };
        (sensors, drive, Watchdog { iwdg }, store)
    };
    #[cfg(feature = "qemu")]
    let (drive, watchdog, store) = (
        Drive {
            last: (0.0, true, false),
        },
        Watchdog {},
        SettingsStore { ram: None },
    );

    Devices {
        sysclk_hz,
        ticker: Ticker::new(core.SYST, sysclk_hz),
        clock,
        tick,
        #[cfg(not(feature = "qemu"))]
        sensors,
        drive,
        console: (console_tx, console_rx),
        hil: (hil_tx, hil_rx),
        watchdog,
        store,
        watchdog_reset,
    }
}
