"""Signal plans per satellite and date (plan.py; the data: plans.yaml)."""
from .plan import PLANS_PATH, PlanRow, SignalPlanError, SignalPlans, default_plans, gps_day, load_plans, parse_plans

__all__ = ["PLANS_PATH", "PlanRow", "SignalPlanError", "SignalPlans", "default_plans", "gps_day", "load_plans",
           "parse_plans"]
