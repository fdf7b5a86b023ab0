//! Path tracing with next-event estimation.
use super::{Integrator, IterationStats, RenderContext};
use crate::color::Rgb;

pub struct PathTracer<'a> {
    ctx: RenderContext<'a>,
}

impl<'a> PathTracer<'a> {
    pub fn new(ctx: RenderContext<'a>) -> Self {
        PathTracer { ctx }
    }
}

impl Integrator for PathTracer<'_> {
    fn render_iteration(&mut self, _iteration: u64, _frame: &mut [Rgb]) -> IterationStats {
        let _ = &self.ctx;
        todo!()
    }
}
