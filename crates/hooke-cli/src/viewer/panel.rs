//! The viewer's side panel: solver, parameters, display options and statistics.

use hooke_core::selfcollide;
use hooke_gpu::render::{Camera, RenderOptions, SceneBounds};

use hooke::live::LiveSimulation;
use hooke::pointer::PushDirection;

pub fn show(
    root: &mut egui::Ui,
    simulation: &mut LiveSimulation,
    options: &mut RenderOptions,
    camera: &mut Camera,
    bounds: &SceneBounds,
    fps: f64,
) {
    egui::Panel::left("controls")
        .resizable(false)
        .show(root, |ui| {
            ui.heading("hooke");
            ui.label("left-drag: grab the cloth, or orbit; right-drag: pan; wheel: zoom");
            ui.label("p while dragging: pin the vertex there; u: unpin those");
            let added = simulation.added_pins();
            if added > 0 && ui.button(format!("Unpin the {added} pinned here")).clicked() {
                simulation.unpin_added();
            }
            ui.separator();

            let mut choice = simulation.choice;
            egui::ComboBox::from_label("solver")
                .selected_text(choice.label())
                .show_ui(ui, |ui| {
                    for c in simulation.choices.clone() {
                        ui.selectable_value(&mut choice, c, c.label());
                    }
                });
            if choice != simulation.choice {
                simulation.switch(choice);
            }

            ui.horizontal(|ui| {
                let label = if simulation.paused { "Resume" } else { "Pause" };
                if ui.button(label).clicked() {
                    simulation.paused = !simulation.paused;
                }
                if ui.button("Step").clicked() {
                    simulation.step_once = true;
                }
                if ui.button("Reset").clicked() {
                    simulation.reset();
                }
                if ui.button("Frame camera").clicked() {
                    *camera = Camera::framing(bounds);
                }
            });
            ui.separator();

            let mut changed = false;
            if ui
                .add(
                    egui::Slider::new(&mut simulation.stiffness_scale, 0.1..=10.0)
                        .logarithmic(true)
                        .text("stiffness x"),
                )
                .changed()
            {
                changed = true;
            }
            if simulation.model().bending_springs > 0 {
                // Rebuilds the solver: applied when the slider is let go, not on every move.
                let slider = ui.add(
                    egui::Slider::new(&mut simulation.bending_scale, 0.0..=4.0)
                        .text("bending x (0: off)"),
                );
                changed |= slider.drag_stopped() || (slider.changed() && !slider.dragged());
                let slider = ui.add(
                    egui::Slider::new(&mut simulation.bending_damping, 0.0..=0.05)
                        .text("bending damping (N s/m)"),
                );
                changed |= slider.drag_stopped() || (slider.changed() && !slider.dragged());
            } else {
                ui.label("no bending springs (add [bending] to the scene)");
            }
            if simulation.model().tearing.is_some() {
                // Rebuilds the solver (the torn springs stay torn): applied when let go.
                let slider = ui.add(
                    egui::Slider::new(&mut simulation.max_stretch, 1.05..=3.0)
                        .text("tear past stretch"),
                );
                changed |= slider.drag_stopped() || (slider.changed() && !slider.dragged());
                ui.label(format!("{} springs torn", simulation.broken_springs()));
            }
            changed |= ui
                .add(
                    egui::Slider::new(&mut simulation.damping, 0.0..=0.01).text("damping c (kg/s)"),
                )
                .changed();
            changed |= ui
                .add(
                    egui::Slider::new(&mut simulation.dt_fraction, 0.05..=1.0)
                        .text("dt / stable dt"),
                )
                .changed();
            ui.label(format!(
                "dt = {:.3e} s (stable up to {:.3e} s)",
                simulation.dt(),
                simulation.max_stable_dt
            ));
            ui.add(
                egui::Slider::new(&mut simulation.steps_per_frame, 1..=200).text("steps per frame"),
            );
            changed |= ui
                .add(
                    egui::Slider::new(&mut simulation.gravity_y, -20.0..=0.0)
                        .text("gravity y (m/s^2)"),
                )
                .changed();
            ui.separator();
            changed |= ui.checkbox(&mut simulation.wind_enabled, "wind").changed();
            ui.add_enabled_ui(simulation.wind_enabled, |ui| {
                changed |= ui
                    .add(
                        egui::Slider::new(&mut simulation.wind_heading_degrees, -180.0..=180.0)
                            .text("heading (deg)"),
                    )
                    .changed();
                changed |= ui
                    .add(
                        egui::Slider::new(&mut simulation.wind_speed, 0.0..=20.0)
                            .text("speed (m/s)"),
                    )
                    .changed();
                changed |= ui
                    .add(
                        egui::Slider::new(&mut simulation.wind_coefficient, 0.0..=5.0)
                            .text("coefficient"),
                    )
                    .changed();
            });
            ui.separator();
            changed |= ui
                .checkbox(&mut simulation.self_collision_enabled, "self-collision")
                .changed();
            ui.add_enabled_ui(simulation.self_collision_enabled, |ui| {
                changed |= ui
                    .add(
                        egui::Slider::new(
                            &mut simulation.self_collision.grids,
                            1..=selfcollide::MAX_GRIDS,
                        )
                        .text("staggered grids K"),
                    )
                    .changed();
                changed |= ui
                    .add(
                        egui::Slider::new(&mut simulation.self_collision.window, 1..=16)
                            .text("window"),
                    )
                    .changed();
            });
            if changed {
                simulation.apply();
            }
            ball_controls(ui, simulation, camera);
            ui.separator();
            ui.checkbox(&mut options.wireframe, "springs (wireframe)");
            ui.checkbox(&mut options.color_by_strain, "colour by strain");
            ui.checkbox(&mut options.show_pins, "mark pinned vertices");
            ui.separator();

            ui.label(format!(
                "{fps:.0} fps, {:.0} steps/s",
                fps * f64::from(simulation.steps_per_frame)
            ));
            ui.label(format!("step {}", simulation.steps_taken()));
            if ui.button("Measure phases").clicked() {
                simulation.measure_phases();
            }
            if let Some((p, source)) = simulation.phases {
                let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
                ui.label(format!(
                    "force {:.3} ms, accumulation {}, integration {:.3} ms, collision {:.3} ms ({:?})",
                    ms(p.force_calculation),
                    p.force_accumulation
                        .map_or("-".to_owned(), |a| format!("{:.3} ms", ms(a))),
                    ms(p.integration),
                    ms(p.collision),
                    source
                ));
            }
            if let Some(message) = &simulation.message {
                ui.colored_label(egui::Color32::RED, message);
            }
        });
}

/// Hold-to-push buttons for the dynamic balls (the arrow keys and PageUp do the same).
fn ball_controls(ui: &mut egui::Ui, simulation: &mut LiveSimulation, camera: &Camera) {
    let balls = simulation.balls();
    if balls.is_empty() {
        return;
    }
    ui.separator();
    ui.label("push a ball (hold; or arrow keys, PageUp)");
    let mut selected = simulation.selected_ball;
    egui::ComboBox::from_label("ball")
        .selected_text(selected.map_or("-".to_owned(), |k| format!("collider {k}")))
        .show_ui(ui, |ui| {
            for &k in &balls {
                ui.selectable_value(&mut selected, Some(k), format!("collider {k}"));
            }
        });
    if selected != simulation.selected_ball {
        simulation.push(glam::DVec3::ZERO);
        simulation.selected_ball = selected;
    }
    ui.add(egui::Slider::new(&mut simulation.push_newtons, 0.0..=50.0).text("force (N)"));
    let mut held = None;
    ui.horizontal(|ui| {
        for direction in PushDirection::ALL {
            if ui.button(direction.name()).is_pointer_button_down_on() {
                held = Some(direction);
            }
        }
    });
    simulation.push(held.map_or(glam::DVec3::ZERO, |d| d.relative_to(camera)));
}
