"""Test-session settings shared by the tests and the doctests of every package folder."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True, scope="session")
def _private_disk_cache(tmp_path_factory: pytest.TempPathFactory):
    """Keep the on-disk cache (pyroute_rel.diskcache) of a test run out of the user's cache folder."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PYROUTE_REL_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
        yield


#: The slowest tests of the quick loop (``pytest -m "not slow"``), measured with ``--durations=0`` on 2026-11-24 (each
#: took 0.3 s or more); marked ``slow`` here in one place, beside the ``@pytest.mark.slow`` decorators in the files.
#: CI runs them all.
SLOW_TESTS = (
    "tests/test_docs.py::test_command",
    "tests/test_avoid_routing.py::test_start_or_finish_on_land_exits_2_naming_the_point",
    "tests/test_crab.py::test_speed_made_good_equals_a_scanned_exact_root",
    "tests/test_hardening.py::test_gate_failure_survives_a_closed_pipe",
    "tests/test_docs.py::test_toml_snippet",
    "tests/test_memory.py::test_estimate_within_2x_of_measured_peak",
    "tests/test_route.py::test_forbidden_arcs_agree_with_the_dp_on_every_course",
    "tests/test_reliability.py::test_voyage_probability_converges_with_the_grid_where_the_per_leg_product_does_not",
    "tests/test_memory.py::test_refusals_are_quick_and_small",
    "tests/test_route.py::test_forbidden_arcs_over_time_varying_weather_and_land",
    "tests/test_cli.py::test_runtime_covers_loading_the_scenario_and_weather",
    "tests/test_hardening.py::test_a_killed_run_leaves_staging_that_the_next_run_removes",
    "tests/test_weather_plausible.py::test_each_variable_out_of_range_is_an_error_naming_file_variable_count_and_place",
    "tests/test_docs.py::test_python_snippets",
    "tests/test_route.py::test_forbidden_arcs_cover_each_leg_of_a_course_through_waypoints",
    "tests/test_route.py::test_forbidden_arcs_are_those_forbidden_at_their_own_departure",
    "tests/test_fuzz.py::test_cli_on_edited_scenarios",
    "tests/test_reliability.py::test_certain_failure_and_no_model",
    "tests/test_reliability.py::test_uniform_conditions_give_the_closed_form",
    "tests/test_architecture.py::test_functions_are_short",
    "tests/test_era5_acceptance.py::test_era5_layout_uniform_field_routes_like_the_uniform_scenario",
    "tests/test_cost.py::test_gridded_uniform_field_costs_like_the_uniform_source",
    "tests/test_refine.py::test_cli_refine_reports_levels",
    "tests/test_outputs.py::test_forbidden_geojson_holds_the_forbidden_arcs_table",
    "tests/test_cli.py::test_departure_sweep_routes_each_departure_like_a_single_route",
    "tests/test_cli.py::test_route_out_writes_every_file",
    "tests/test_reliability.py::test_criteria_see_the_heading_the_craft_steers_in_a_current",
    "tests/test_avoid_routing.py::test_real_course_example_end_to_end",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.nodeid.split("[", 1)[0] in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
