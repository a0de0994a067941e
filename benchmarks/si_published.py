"""StructuralIdentifiability.jl's published identifiable functions (with states), transcribed (data only).

Source: SciML/StructuralIdentifiability.jl @ b7bff91634575095369190ca7d418fe41f98cac2,
``benchmarking/IdentifiableFunctions/results/<name>/result_(normalforms, 2)_with_states``: the return value of
``find_identifiable_functions(ode, with_states=true, strategy=(:normalforms, 2))`` in the run of 2023-09-15 whose
times ``si_models.py`` quotes. Keys are ``si_models.MODELS``'s; ``<name>`` is the model's ``name``. Written as
there, with Julia's ``//`` -> ``/`` and ``^`` -> ``**``, and the renames of ``si_models`` applied (SEIRT's lambda).

These generators describe SI.jl's 2023 model files. Where ``si_models`` notes that a 2023 file is not the model of
benchmarks.jl (its ``note`` says "2023 model file"), they are of that other model and are not compared.
"""

PUBLISHED = {'akt': ['reaction_8_k1', 'reaction_5_k2', 'reaction_2_k2', 'reaction_3_k1', 'reaction_6_k1', 'reaction_7_k1',
         'reaction_4_k1', 'pS6*reaction_2_k1', 'reaction_2_k1*pAkt_S6', 'reaction_2_k1*S6', 'pAkt*reaction_2_k1',
         'Akt*reaction_2_k1', 'pEGFR_Akt*reaction_2_k1', 'pEGFR*reaction_2_k1', 'pS6*reaction_5_k1', 'pS6*a1',
         'pS6*a3', 'a2*pS6', 'reaction_9_k1*reaction_2_k1*EGF_EGFR',
         'reaction_1_k1 - reaction_9_k1 - reaction_1_k2'],
 'bilirubin2': ['x1', 'k01', 'x3 + x2 + x4', 'k12 + k13 + k14', 'k31 + k21 + k41', 'x3*x2 + x3*x4 + x2*x4',
                'k12*x2 + x3*k13 + x4*k14', 'k12*k13 + k12*k14 + k13*k14', 'k31*x3 + k21*x2 + x4*k41',
                'k31*k13 + k21*k12 + k14*k41',
                '(-x3**2*x2 + x3**2*x4 + x3*x2**2 - x3*x4**2 - x2**2*x4 + x2*x4**2)/(k12*x3 - k12*x4 - x3*k14 - '
                'k13*x2 + k13*x4 + x2*k14)',
                '(k12*x3**2 - k12*x4**2 - x3**2*k14 - k13*x2**2 + k13*x4**2 + x2**2*k14)/(k12*x3 - k12*x4 - x3*k14 - '
                'k13*x2 + k13*x4 + x2*k14)'],
 'biohydrogenation': ['x5', 'x4', 'k7', 'k6', 'k5', 'k10**2', 'k9*k10', 'k10 - 2*x6', 'k8 + x6'],
 'bruno2016': ['beta10', 'beta', 'kbeta', 'kbeta10', 'cry*kcryOH', 'kcrybeta + kcryOH'],
 'cd8': ['M', 'S', 'E', 'N', 'mu_P', 'mu_LL', 'mu_PL', 'mu_PE', 'delta_LM', 'mu_M', 'mu_N', 'delta_EL', 'mu_LE',
         'mu_EE', 'P*rho_E', 'delta_NE*P', 'rho_P*P'],
 'cgv1990': ['q7', 'q3', 'q1', 'k7', 'k6', 'k4', 'k3', 'q36*q35', 'q36 + q35', 'S*V3 + 25*V36*R', 'S*V36 + R*V3',
             '(V36**2 + 1/25*V3**2)/(V36*V3)', '(-S*V3 + 25*V36*R)/(q36 - q35)',
             '(-k5*V36 + 1/5*k5*V3)/(q36*V3 - q35*V3)'],
 'cholera': ['R', 'W', 'I', 'S', 'a', 'xi', 'k', 'bw', 'mu', 'gam', 'bi'],
 'clv1_2o': ['pi2', 'pi1', 'A22', 'A12', 'A32', 'B11', 'g1', 'A31', 'g2', 'g3', 'A11', 'A21', 'B31', 'B21', 'A13*pi3',
             'A33*pi3', 'A23*pi3'],
 'crauste': ['M', 'S', 'E', 'N', 'mu_P', 'mu_LL', 'mu_PL', 'mu_PE', 'delta_LM', 'mu_M', 'mu_N', 'delta_EL', 'mu_LE',
             'mu_EE', 'P*rho_E', 'delta_NE*P', 'rho_P*P'],
 'crn': ['x6', 'x5', 'x4', 'x3', 'x2', 'x1', 'k1', 'k6', 'k2', 'k4', 'k3', 'k5'],
 'fujita': ['reaction_8_k1', 'reaction_5_k2', 'reaction_2_k2', 'reaction_3_k1', 'reaction_6_k1', 'reaction_7_k1',
            'reaction_4_k1', 'pS6*reaction_2_k1', 'reaction_2_k1*pAkt_S6', 'reaction_2_k1*S6', 'pAkt*reaction_2_k1',
            'Akt*reaction_2_k1', 'pEGFR_Akt*reaction_2_k1', 'pEGFR*reaction_2_k1', 'pS6*reaction_5_k1', 'pS6*a1',
            'pS6*a3', 'a2*pS6', 'reaction_9_k1*reaction_2_k1*EGF_EGFR',
            'reaction_1_k1 - reaction_9_k1 - reaction_1_k2'],
 'gen_lv_1o': ['x1', 'r2', 'beta11', 'r1', 'beta21', 'x2*beta12', 'beta22*x2'],
 'glv2': ['x2', 'x1', 'r2', 'beta12', 'beta11', 'r1', 'beta21', 'beta22'],
 'goodwin': ['x4', 'x1', 'sigma', 'c', 'b', 'delta*beta', 'delta + beta', '(alpha*gama)/x3',
             '(gama*x2 + x3*beta)/x3'],
 'hdnl': ['x20', 'x19', 'x18', 'x17', 'x16', 'x15', 'x14', 'x13', 'x12', 'x11', 'x10', 'x9', 'x8', 'x7', 'x6', 'x5',
          'x4', 'x3', 'x2', 'x1', 'p19', 'p11', 'p16', 'p3', 'p12', 'p17', 'vm', 'p10', 'p8', 'p13', 'p4', 'p14',
          'p5', 'p15', 'p6', 'p9', 'km', 'p1', 'p18', 'p2', 'p20', 'p7'],
 'hiv': ['z', 'w', 'a', 'u', 'd', 'h', 'b', 'v*beta', 'x/y', 'q/y', 'lm/y', '(k*y)/v', '(k*beta)/(c*y)'],
 'hiv2': ['x4', 'x1', 's', 'd', 'b', 'k2*q2', 'c*w1*w2 + c*k1*w2', 'c + w1 + k1 + w2',
          'w1*x4 + k2*x3 + k1*x4 + w2*x4', 'c*w1 + c*k1 + c*w2 + w1*w2 + k1*w2',
          '(q1*k1*x4 - k2*x3*q2 - w2*q2*x4)/(q2*x4)', '(c*x3*x4 - k2*x3**2 - x3*w2*x4 + k1*x2*x4)/(q2*x4)'],
 'kd1999': ['Tj', 'T', 'Cb', 'Ca', 'Ta', 'Ca0', 'Vh', 'V', 'Th', 'k0*Arr', 'E/R', 'UA/DH', '(ro*cp)/DH',
            '(cph*roh)/DH'],
 'lipolysis': ['x5', 'x4', 'x3', 'x2', 'x1', 'k2', 'k4', 'k3'],
 'llw1987': ['x3', 'x2*x1', 'p3*p1', 'p2*p4', 'p3 + p1', 'p2*x2 + p4*x1', '(p2*x2 - p4*x1)/(p3 - p1)'],
 'lv': ['x1', 'd', 'x2*c', 'a*b', 'a + b'],
 'mapk_5out': ['S11', 'S10', 'S01', 'S00', 'F', 'K', 'FS11', 'FS10', 'FS01', 'KS10', 'KS01', 'KS00', 'gamma0100',
               'gamma1110', 'a01', 'c1011', 'b01', 'a00', 'gamma1101', 'b10', 'c0010', 'c0011', 'gamma1100',
               'alpha01', 'beta01', 'alpha11', 'beta10', 'c0111', 'beta11', 'b00', 'alpha10', 'gamma1000', 'a10',
               'c0001'],
 'mapk_6out': ['S11', 'S10', 'S01', 'S00', 'F', 'K', 'FS11', 'FS10', 'FS01', 'KS10', 'KS01', 'KS00', 'gamma0100',
               'gamma1110', 'a01', 'c1011', 'b01', 'a00', 'gamma1101', 'b10', 'c0010', 'c0011', 'gamma1100',
               'alpha01', 'beta01', 'alpha11', 'beta10', 'c0111', 'beta11', 'b00', 'alpha10', 'gamma1000', 'a10',
               'c0001'],
 'p53': ['x4', 'x3', 'x2', 'x1', 'p14', 'p5', 'p24', 'p15', 'p12', 'p6', 'p9', 'p21', 'p17', 'p20', 'p11', 'p16',
         'p25', 'p10', 'p3', 'p1', 'p23', 'p8', 'p18', 'p13', 'p4', 'p7', 'p22**4'],
 'pharm': ['x3', 'x2', 'x1', 'x0', 'a1', 'b1', 'kc', 'b2', 'n', 'ka', 'a2'],
 'phos': ['x3', 'x1', 'x2', 'x4', 'x6', 'x5', 'k1', 'k6', 'k2', 'k4', 'k3', 'k5'],
 'pivastatin': ['k2', 'k4', 'r1', 'k3', 'r3', 'x3*k1', 'k1*x2', 'k1*x1', 'k*x3', 'T0*k1'],
 'pk1': ['x1', 'k6', 'k4', 'k5', 's2*x4', 's2*x2', 's2*k1', 's3*x3', 's3*k2', 'k2 + k1', 'k3 + k7',
         '(k2*s2)/(k3*k2 + k3*k1)'],
 'pk2': ['x3', 'x2', 'x1', 'x0', 'a1', 'b1', 'kc', 'b2', 'n', 'ka', 'a2'],
 'qy': ['P4', 'P3', 'P2', 'P1', 'P0', 'Ks', 'Mar', 'alpa', 'Mar*P5 + beta', 'siga1 + M + siga2',
        'siga1*M + siga1*siga2 + M*siga2',
        '(siga1*phi*M*siga2 - siga1*M*siga2 - phi*M*Mar*siga2 + M*Mar*siga2)/(siga1*beta_SA + phi*Mar*beta_SA - '
        'Mar*beta_SA)',
        '(siga1*beta_SI*phi*siga2 - siga1*beta_SI*siga2 - siga1*phi*siga2*beta_SA - siga1*M*beta_SA - '
        'beta_SI*phi*Mar*siga2 + beta_SI*Mar*siga2 - phi*M*Mar*beta_SA + M*Mar*beta_SA)/(siga1*beta_SA + '
        'phi*Mar*beta_SA - Mar*beta_SA)',
        '(siga1**2*beta_SI*beta_SA - siga1**2*beta_SA**2 + siga1*beta_SI**2*phi*siga2 - siga1*beta_SI**2*siga2 + '
        'siga1*beta_SI*phi*Mar*beta_SA - 2*siga1*beta_SI*phi*siga2*beta_SA - siga1*beta_SI*M*beta_SA - '
        'siga1*beta_SI*Mar*beta_SA + siga1*beta_SI*siga2*beta_SA - siga1*phi*Mar*beta_SA**2 + '
        'siga1*phi*siga2*beta_SA**2 + siga1*Mar*beta_SA**2 - beta_SI**2*phi*Mar*siga2 + beta_SI**2*Mar*siga2 - '
        'beta_SI*phi*M*Mar*beta_SA + beta_SI*phi*Mar*siga2*beta_SA + beta_SI*M*Mar*beta_SA - '
        'beta_SI*Mar*siga2*beta_SA)/(siga1*M*beta_SA + phi*M*Mar*beta_SA - M*Mar*beta_SA)',
        '(siga1**4*beta_SI*beta_SA**2 - siga1**4*beta_SA**3 + 2*siga1**3*beta_SI**2*phi*siga2*beta_SA - '
        '2*siga1**3*beta_SI**2*siga2*beta_SA + 2*siga1**3*beta_SI*phi*Mar*beta_SA**2 - '
        '4*siga1**3*beta_SI*phi*siga2*beta_SA**2 - siga1**3*beta_SI*M*beta_SA**2 - 2*siga1**3*beta_SI*Mar*beta_SA**2 '
        '+ 3*siga1**3*beta_SI*siga2*beta_SA**2 - 2*siga1**3*phi*Mar*beta_SA**3 + 2*siga1**3*phi*siga2*beta_SA**3 + '
        'siga1**3*M*beta_SA**3 + 2*siga1**3*Mar*beta_SA**3 - siga1**3*siga2*beta_SA**3 + '
        'siga1**2*beta_SI**3*phi**2*siga2**2 - 2*siga1**2*beta_SI**3*phi*siga2**2 + siga1**2*beta_SI**3*siga2**2 + '
        '2*siga1**2*beta_SI**2*phi**2*Mar*siga2*beta_SA - 3*siga1**2*beta_SI**2*phi**2*siga2**2*beta_SA - '
        'siga1**2*beta_SI**2*phi*M*siga2*beta_SA - 6*siga1**2*beta_SI**2*phi*Mar*siga2*beta_SA + '
        '5*siga1**2*beta_SI**2*phi*siga2**2*beta_SA + siga1**2*beta_SI**2*M*siga2*beta_SA + '
        '4*siga1**2*beta_SI**2*Mar*siga2*beta_SA - 2*siga1**2*beta_SI**2*siga2**2*beta_SA + '
        'siga1**2*beta_SI*phi**2*Mar**2*beta_SA**2 - 4*siga1**2*beta_SI*phi**2*Mar*siga2*beta_SA**2 + '
        '3*siga1**2*beta_SI*phi**2*siga2**2*beta_SA**2 - 2*siga1**2*beta_SI*phi*M*Mar*beta_SA**2 + '
        '2*siga1**2*beta_SI*phi*M*siga2*beta_SA**2 - 2*siga1**2*beta_SI*phi*Mar**2*beta_SA**2 + '
        '10*siga1**2*beta_SI*phi*Mar*siga2*beta_SA**2 - 4*siga1**2*beta_SI*phi*siga2**2*beta_SA**2 + '
        '2*siga1**2*beta_SI*M*Mar*beta_SA**2 - siga1**2*beta_SI*M*siga2*beta_SA**2 + '
        'siga1**2*beta_SI*Mar**2*beta_SA**2 - 6*siga1**2*beta_SI*Mar*siga2*beta_SA**2 + '
        'siga1**2*beta_SI*siga2**2*beta_SA**2 - siga1**2*phi**2*Mar**2*beta_SA**3 + '
        '2*siga1**2*phi**2*Mar*siga2*beta_SA**3 - siga1**2*phi**2*siga2**2*beta_SA**3 + '
        '2*siga1**2*phi*M*Mar*beta_SA**3 - siga1**2*phi*M*siga2*beta_SA**3 + 2*siga1**2*phi*Mar**2*beta_SA**3 - '
        '4*siga1**2*phi*Mar*siga2*beta_SA**3 + siga1**2*phi*siga2**2*beta_SA**3 - 2*siga1**2*M*Mar*beta_SA**3 - '
        'siga1**2*Mar**2*beta_SA**3 + 2*siga1**2*Mar*siga2*beta_SA**3 - 2*siga1*beta_SI**3*phi**2*Mar*siga2**2 + '
        '4*siga1*beta_SI**3*phi*Mar*siga2**2 - 2*siga1*beta_SI**3*Mar*siga2**2 - '
        'siga1*beta_SI**2*phi**2*M*Mar*siga2*beta_SA - 2*siga1*beta_SI**2*phi**2*Mar**2*siga2*beta_SA + '
        '5*siga1*beta_SI**2*phi**2*Mar*siga2**2*beta_SA + 3*siga1*beta_SI**2*phi*M*Mar*siga2*beta_SA + '
        '4*siga1*beta_SI**2*phi*Mar**2*siga2*beta_SA - 9*siga1*beta_SI**2*phi*Mar*siga2**2*beta_SA - '
        '2*siga1*beta_SI**2*M*Mar*siga2*beta_SA - 2*siga1*beta_SI**2*Mar**2*siga2*beta_SA + '
        '4*siga1*beta_SI**2*Mar*siga2**2*beta_SA - siga1*beta_SI*phi**2*M*Mar**2*beta_SA**2 + '
        '2*siga1*beta_SI*phi**2*M*Mar*siga2*beta_SA**2 + 3*siga1*beta_SI*phi**2*Mar**2*siga2*beta_SA**2 - '
        '4*siga1*beta_SI*phi**2*Mar*siga2**2*beta_SA**2 + 2*siga1*beta_SI*phi*M*Mar**2*beta_SA**2 - '
        '4*siga1*beta_SI*phi*M*Mar*siga2*beta_SA**2 - 6*siga1*beta_SI*phi*Mar**2*siga2*beta_SA**2 + '
        '6*siga1*beta_SI*phi*Mar*siga2**2*beta_SA**2 - siga1*beta_SI*M*Mar**2*beta_SA**2 + '
        '2*siga1*beta_SI*M*Mar*siga2*beta_SA**2 + 3*siga1*beta_SI*Mar**2*siga2*beta_SA**2 - '
        '2*siga1*beta_SI*Mar*siga2**2*beta_SA**2 + siga1*phi**2*M*Mar**2*beta_SA**3 - '
        'siga1*phi**2*M*Mar*siga2*beta_SA**3 - siga1*phi**2*Mar**2*siga2*beta_SA**3 + '
        'siga1*phi**2*Mar*siga2**2*beta_SA**3 - 2*siga1*phi*M*Mar**2*beta_SA**3 + siga1*phi*M*Mar*siga2*beta_SA**3 + '
        '2*siga1*phi*Mar**2*siga2*beta_SA**3 - siga1*phi*Mar*siga2**2*beta_SA**3 + siga1*M*Mar**2*beta_SA**3 - '
        'siga1*Mar**2*siga2*beta_SA**3 + beta_SI**3*phi**2*Mar**2*siga2**2 - 2*beta_SI**3*phi*Mar**2*siga2**2 + '
        'beta_SI**3*Mar**2*siga2**2 + beta_SI**2*phi**2*M*Mar**2*siga2*beta_SA - '
        '2*beta_SI**2*phi**2*Mar**2*siga2**2*beta_SA - 2*beta_SI**2*phi*M*Mar**2*siga2*beta_SA + '
        '4*beta_SI**2*phi*Mar**2*siga2**2*beta_SA + beta_SI**2*M*Mar**2*siga2*beta_SA - '
        '2*beta_SI**2*Mar**2*siga2**2*beta_SA - beta_SI*phi**2*M*Mar**2*siga2*beta_SA**2 + '
        'beta_SI*phi**2*Mar**2*siga2**2*beta_SA**2 + 2*beta_SI*phi*M*Mar**2*siga2*beta_SA**2 - '
        '2*beta_SI*phi*Mar**2*siga2**2*beta_SA**2 - beta_SI*M*Mar**2*siga2*beta_SA**2 + '
        'beta_SI*Mar**2*siga2**2*beta_SA**2)/(siga1**2*phi*M**2*siga2*beta_SA - siga1**2*M**2*siga2*beta_SA + '
        'siga1*phi**2*M**2*Mar*siga2*beta_SA - 3*siga1*phi*M**2*Mar*siga2*beta_SA + 2*siga1*M**2*Mar*siga2*beta_SA - '
        'phi**2*M**2*Mar**2*siga2*beta_SA + 2*phi*M**2*Mar**2*siga2*beta_SA - M**2*Mar**2*siga2*beta_SA)'],
 'seaijrc': ['Ninv', 'C', 'J', 'I', 'g1', 'k', 'g2', 'alpha', 'b', 'E*r', 'S*r', 'A*q', '(A*r)/(r - 1)'],
 'seir2t': ['Cu', 'N', 'In', 'E', 'S', 'nu', 'b', 'a'],
 'seir34': ['S', 'N', 'A', 'mu', 'K*I', 'K*epsilon', 'gamma*I', 'E + I', 'gamma + epsilon',
            '(gamma*r*beta + epsilon*r*beta)/gamma'],
 'seir36_ref': ['F', 'Di', 'De', 'I', 'E', 'S', 'q', 'nu', 'N', 'beta_d', 'gamma_d', 'phi_e', 'beta', 'mu_i', 's',
                'mu_d', 's_d', 'mu_0', 'phi', 'gamma'],
 'seir_1': ['Q', 'gamma', 'I*psi', 'beta*I', 'beta*gamma - beta*v', 'v*psi - v - psi',
            '(gamma*S)/(I*gamma*psi - I*gamma - I*psi)',
            '(I*gamma*psi - I*psi + gamma*E)/(I*gamma*psi - I*gamma - I*psi)'],
 'seirt': ['N', 'I', 'beta', 'alpha*S', 'lam*alpha', 'lam + alpha', 'alpha*I + alpha*E'],
 'sir21': ['D', 'C', 'I', 'S', 'N', 'beta', 'pp', 'r', 'q', 'mu'],
 'sir24': ['I', 'S', 'K', 'c*phi', '-A + mu', 'gamma + A'],
 'sir6': ['N', 'gamma', 'I*K', 'K*S', 'beta*I'],
 'sirs_forced': ['r', 'i', 's', 'g', 'mu', 'b0', 'nu', 'M**2', 'b1*x1', '(M*x2)/x1'],
 'siwr_multiout': ['R', 'W', 'I', 'S', 'a', 'xi', 'k', 'bw', 'mu', 'gam', 'bi'],
 'siwr_orig': ['R', 'W', 'I', 'S', 'a', 'xi', 'k', 'bw', 'mu', 'gam', 'bi'],
 'sliqr': ['In', 's', 'Ninv', 'b', 'S*a', 'g + a', 's*Q - Q*a', 'In*a + Q*a + a*L', 'e*s*g - s*g + g*a',
           '(e*S - S)/(e*Q)'],
 'st': ['Dd', 'T', 'S + R', 'rR*R - S*d*T + S*r - dr*R*T', 'e - rR + dr*W + d*W + g - r + a*W',
        'e - rR + dr*T + d*T + g - r + a*T', '(rR*d - dr*r)/(dr - d)', '(S*d + dr*R)/(dr + d + a)',
        '(dr*d + dr*a)/(dr**2 + d**2 + 2*d*a + a**2)',
        '(-e*dr**2*g + 2*e*dr*d*g + e*dr*g*a - e*d**2*g - e*d*g*a - rR*dr*g*a + rR*d*g*a + rR*g*a**2 + dr*g**2*a + '
        'dr*g*r*a - d*g**2*a - d*g*r*a - g*r*a**2)/(S**2*dr*a - S**2*d*a - S*dr**2*R + 2*S*dr*R*d + S*dr*R*a - '
        'S*R*d**2 - S*R*d*a)',
        '(-e*S*dr**2 + 2*e*S*dr*d + e*S*dr*a - e*S*d**2 - e*S*d*a - rR*S*dr*a + rR*S*d*a + rR*S*a**2 + 2*S*dr*g*a + '
        'S*dr*r*a - 2*S*d*g*a - S*d*r*a - S*r*a**2 - dr**2*R*g + 2*dr*R*d*g + dr*R*g*a - R*d**2*g - '
        'R*d*g*a)/(S**2*dr*a - S**2*d*a - S*dr**2*R + 2*S*dr*R*d + S*dr*R*a - S*R*d**2 - S*R*d*a)'],
 'transfection': ['GFP', 'd3', 'd1', 'b', 'd2*mRNAenz', 'enz*d2', 'd2*mRNA', 'kTL*mRNAenz'],
 'treatment': ['N', 'Tr', 'S*g', 'b*S', 'nu + d*g', 'nu*g + nu*a', 'nu + g + a', 'In*g + Tr*g + Tr*a']}
