from deepphy.envs import Observation, Task
from deepphy.prompts import EnvPrompt
from toy_env.env import RAIL
from toy_env.space import FORCES, MAX_PUSHES


class CartPrompt(EnvPrompt):
    def rules(self, task: Task, observation: Observation) -> str:
        return (f"Stop the cart on the flag of a {RAIL}-cell rail. Each push(F), F in {FORCES}, adds F to the "
                f"velocity; then the cart moves. At most {MAX_PUSHES} pushes.")

    def prediction_hint(self) -> str:
        return "where the cart will be"

    def example(self, observation: Observation) -> str:
        return "push(1)"
