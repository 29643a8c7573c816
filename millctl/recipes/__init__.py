"""Scripted milling recipes: the schema, the pre-flight check and plan, and the runner."""

from millctl.recipes.plan import RecipePlan, StepPlan, Violation, plan_recipe
from millctl.recipes.schema import LoadedRecipe, Recipe, load_recipe, parse_recipe

__all__ = [
    "LoadedRecipe",
    "Recipe",
    "RecipePlan",
    "StepPlan",
    "Violation",
    "load_recipe",
    "parse_recipe",
    "plan_recipe",
]
